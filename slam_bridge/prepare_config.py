"""The settings of ``lts prepare``, as given and as recorded in a scene's ``scene.json``."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from rig.camera import CameraModel
from rig.errors import InputError

#: Default longest image side of a scene. CPU training time grows with the pixels per image: a
#: 1920x1080 recording at 640x360 trains in a few times the 320x240 room demo's time, at full size
#: in tens of times. Recordings no larger (the demo, the quick run) are untouched. GPU users may
#: pass a larger value or 0 (full size).
DEFAULT_MAX_SIZE = 640

#: Default most metres a camera travels between keyframes, whatever the interval: a car at 10 m/s
#: would leave 5 m between keyframes 0.5 s apart (the room's robot 0.22 m), where driving datasets'
#: 10 Hz frames lie 1 m apart.
DEFAULT_MAX_TRAVEL_M = 1.0


@dataclass(frozen=True)
class PrepareConfig:
    """Settings of the scene builder.

    Attributes:
        keyframe_interval_s: one keyframe per this many seconds of camera frames; None: 0.5 s (the
            paper's), or down to 0.2 s so that a recording shorter than 20 s still gives 40
            (:func:`~slam_bridge.keyframe_selection.default_interval`). A scene records the interval
            it was made with.
        keyframe_min_motion: ``(metres, degrees)``: choose keyframes by motion instead of time.
        keyframe_max_travel_m: with keyframes by time, also take one wherever the camera has moved
            this far since the last (0: by time alone). See :data:`DEFAULT_MAX_TRAVEL_M`.
        test_every: every n-th keyframe is held out for testing.
        occlusion_window_px: window of the see-through test on LiDAR depth (0 disables it).
        image_topic, points_topic: choose topics when a session has several.
        normals_dir: a folder of precomputed normal maps (e.g. from a monocular normal network) to
            use instead of the SLAM mesh's normals: see :func:`~slam_bridge.keyframe_normals.read_normal_map`.
        sparse_points: triangulate COLMAP sparse points from the keyframes (the TS+ baseline's
            start, ours' camera-only seeds).
        refine_poses: refine the keyframe poses against the SLAM mesh, guarded by held-out
            matches (:mod:`slam_bridge.pose_refinement`); LiDAR points, normals and sparse points
            then use the refined poses.
        max_size: longest side (pixels) of the scene's images; larger recordings are scaled down
            to it (0: full size). See :data:`DEFAULT_MAX_SIZE`.
        downscale: divide the recording's image size by this whole number (1: keep it).
    """

    keyframe_interval_s: float | None = None
    keyframe_min_motion: tuple[float, float] | None = None
    keyframe_max_travel_m: float = DEFAULT_MAX_TRAVEL_M
    test_every: int = 8
    occlusion_window_px: int = 7
    image_topic: str | None = None
    points_topic: str | None = None
    normals_dir: Path | None = None
    sparse_points: bool = False
    refine_poses: bool = False
    max_size: int = DEFAULT_MAX_SIZE
    downscale: int = 1

    def __post_init__(self) -> None:
        if self.keyframe_interval_s is not None and not self.keyframe_interval_s >= 0:
            raise InputError(
                f"expected seconds >= 0 (0: every frame), got {self.keyframe_interval_s}",
                field="keyframe_interval_s",
            )
        if self.keyframe_min_motion is not None and not min(self.keyframe_min_motion) >= 0:
            motion = self.keyframe_min_motion
            raise InputError(f"expected metres and degrees >= 0, got {motion}", field="keyframe_min_motion")
        if not self.keyframe_max_travel_m >= 0:
            raise InputError(
                f"expected metres >= 0 (0: by time alone), got {self.keyframe_max_travel_m}",
                field="keyframe_max_travel_m",
            )
        if self.test_every < 0:
            raise InputError(
                f"expected a whole number >= 0 (0: none), got {self.test_every}", field="test_every"
            )
        for name, least in (("max_size", 0), ("downscale", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise InputError(f"expected a whole number >= {least}, got {value!r}", field=name)

    def scene_camera(self, camera: CameraModel) -> CameraModel:
        """The distortion-free pinhole camera of the scene's images: ``camera`` undistorted, scaled
        down by :attr:`downscale` and further to :attr:`max_size` where it is larger."""
        scale = 1 / self.downscale
        if self.max_size:
            scale = min(scale, self.max_size / max(camera.width, camera.height))
        size = (max(1, round(camera.width * scale)), max(1, round(camera.height * scale)))
        target = camera.undistorted()
        return target if size == target.size else target.scaled(*size)

    def to_json(self) -> dict[str, Any]:
        """Every field as a JSON value (paths as strings, the motion pair as a list)."""
        data = asdict(self)
        data["normals_dir"] = None if self.normals_dir is None else str(self.normals_dir)
        if self.keyframe_min_motion is not None:
            data["keyframe_min_motion"] = list(self.keyframe_min_motion)
        return data

    @classmethod
    def from_json(cls, data: Any, path: Path) -> PrepareConfig:
        """The config :meth:`to_json` wrote; an error naming ``path`` when a field is missing or unknown."""
        names = {f.name for f in fields(cls)}
        if isinstance(data, dict) and "keyframe_max_travel_m" not in data:
            data = {**data, "keyframe_max_travel_m": 0.0}  # made before the rule: keyframes by time alone
        if not isinstance(data, dict) or set(data) != names:
            got = sorted(data) if isinstance(data, dict) else type(data).__name__
            raise InputError(f"expected the fields {sorted(names)}, got {got}", path=path, field="options")
        motion = data["keyframe_min_motion"]
        normals = data["normals_dir"]
        try:
            return cls(
                **{
                    **data,
                    "keyframe_min_motion": None if motion is None else tuple(motion),
                    "normals_dir": None if normals is None else Path(normals),
                }
            )
        except InputError as exc:
            raise InputError(exc.reason, path=path, field=f"options.{exc.field}") from None
