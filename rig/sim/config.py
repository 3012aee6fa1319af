"""Options of a simulated run; ``scene.yaml`` stores them so that a run can be regenerated."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from rig.camera import CameraModel
from rig.data_file import load_data_file
from rig.errors import InputError
from rig.sim.scenes import PRESETS

#: The rig and run length of the indoor presets and user meshes; a preset may change these
#: (``sensor_defaults``).
SENSOR_DEFAULTS = {
    "duration_s": 20.0,
    "carrier": "wheeled",
    "lidar": "mid360",
    "width": 320,
    "height": 240,
    "max_range_m": 40.0,
}
#: What ``--quick`` changes: a short run at a small image size, for tests and smoke checks.
QUICK = {"duration_s": 3.0, "width": 160, "height": 120, "lidar_points": 8000, "from_rest": False}


@dataclass(frozen=True)
class SimConfig:
    """Everything that determines a simulated run (with the seed, runs are bit-reproducible).

    Attributes:
        preset: procedural scene (a key of :data:`~rig.sim.scenes.PRESETS`); ignored with ``mesh``.
        mesh, trajectory: a user mesh and camera-to-world trajectory (OpenCV camera axes)
            instead of a preset; ``trajectory_rate_hz`` times trajectories without stamps.
        seed: seeds scene layout, textures, path wobble, clocks and every noise.
        duration_s: seconds of motion along a preset's path (the preset's: 20, ``floor`` 120).
        speed_mps: cruising speed along a preset's path (m/s; ``None`` takes the preset's); on the
            ``street`` the cars in the robot's lane drive at it too.
        from_rest: the robot starts from rest and stops at the end; ``False``: it is moving at
            its cruising speed from the first frame to the last (the quick run's 3 s).
        carrier: ``wheeled`` (camera 0.35–0.55 m high), ``handheld`` (1.3–1.5 m) or ``car``
            (1.6–1.7 m).
        fps, width, height, camera_model: the camera (``pinhole`` or ``fisheye``).
        carrier, width, height, lidar and max_range_m left ``None`` take the preset's
        ``sensor_defaults``, then :data:`SENSOR_DEFAULTS`.
        image_format: how frames are stored in the session (``png`` lossless, ``jpeg``, ``raw``).
        image_noise, exposure_jitter: pixel noise std (grey levels) and per-frame gain std.
        lidar, lidar_rate_hz, lidar_points, range_noise_m, dropout, max_range_m: the LiDAR.
        imu_rate_hz: IMU sample rate.
        time_offset_s: camera–LiDAR time offset written to calib.yaml (add to LiDAR times).
        traffic: the preset's moving objects drive (``street``); False leaves the scene static.
    """

    preset: str = "room"
    mesh: str | None = None
    trajectory: str | None = None
    trajectory_rate_hz: float = 30.0
    seed: int = 0
    duration_s: float | None = None
    speed_mps: float | None = None
    from_rest: bool = True
    carrier: str | None = None
    fps: float = 30.0
    width: int | None = None
    height: int | None = None
    camera_model: str = "pinhole"
    image_format: str = "png"
    image_noise: float = 0.0
    exposure_jitter: float = 0.0
    lidar: str | None = None
    lidar_rate_hz: float = 10.0
    lidar_points: int = 20000
    range_noise_m: float = 0.015
    dropout: float = 0.02
    max_range_m: float | None = None
    imu_rate_hz: float = 200.0
    time_offset_s: float = 0.015
    traffic: bool = True

    def __post_init__(self) -> None:
        preset = PRESETS.get(self.preset) if self.mesh is None else None
        defaults = {**SENSOR_DEFAULTS, **(preset.sensor_defaults if preset else {})}
        for name, value in defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, value)
        if preset is not None and self.speed_mps is None:
            object.__setattr__(self, "speed_mps", preset.speed_mps)
        if self.speed_mps is not None and not self.speed_mps > 0:
            raise InputError(f"must be positive, got {self.speed_mps}", field="speed_mps")
        if (self.mesh is None) != (self.trajectory is None):
            raise InputError("--mesh and --trajectory go together", field="mesh/trajectory")
        for name in (
            "duration_s",
            "fps",
            "lidar_rate_hz",
            "imu_rate_hz",
            "trajectory_rate_hz",
            "max_range_m",
        ):
            if not getattr(self, name) > 0:
                raise InputError(f"must be positive, got {getattr(self, name)}", field=name)
        for name in ("image_noise", "exposure_jitter"):
            if not getattr(self, name) >= 0:
                raise InputError(f"expected a standard deviation >= 0, got {getattr(self, name)}", field=name)
        if self.seed < 0:
            raise InputError(f"expected a whole number >= 0, got {self.seed}", field="seed")
        if self.width < 8 or self.height < 8:
            raise InputError(f"image too small: {self.width}x{self.height}", field="width/height")
        if self.image_format not in ("png", "jpeg", "raw"):
            raise InputError(
                f"unknown {self.image_format!r}; expected png, jpeg or raw", field="image_format"
            )
        if self.carrier not in ("wheeled", "handheld", "car"):
            raise InputError(f"unknown {self.carrier!r}; expected wheeled, handheld or car", field="carrier")
        if abs(self.time_offset_s) > 1.0:
            raise InputError(f"expected at most 1 s, got {self.time_offset_s}", field="time_offset_s")

    def quick(self, **kept: Any) -> SimConfig:
        """This configuration with the :data:`QUICK` settings, but for the fields in ``kept``
        (field → value, e.g. a width given beside ``lts sim --quick``)."""
        return replace(self, **{**QUICK, **kept})

    def camera(self) -> CameraModel:
        """The simulated camera: ~65° (pinhole) or ~130° (fisheye) horizontal field of view."""
        w, h = self.width, self.height
        if self.camera_model == "fisheye":
            f = 0.45 * w
            dist = [0.02, -0.01, 0.003, -0.001]
        elif self.camera_model == "pinhole":
            f = 0.78 * w
            dist = [-0.10, 0.04, 0.0005, -0.0003, 0.0]
        else:
            raise InputError(
                f"unknown {self.camera_model!r}; expected pinhole or fisheye", field="camera_model"
            )
        K = np.array([[f, 0.0, (w - 1) / 2], [0.0, f, (h - 1) / 2], [0.0, 0.0, 1.0]])
        return CameraModel(self.camera_model, w, h, K, np.array(dist))  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_scene_yaml(cls, path: str | Path) -> SimConfig:
        """The configuration stored under ``config:`` in a ``scene.yaml``."""
        path = Path(path)
        data = load_data_file(path, "YAML", "scene file")
        config = data.get("config") if isinstance(data, dict) else None
        if not isinstance(config, dict):
            raise InputError("missing", path=path, field="config")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(config) - known)
        if unknown:
            raise InputError(f"unknown option(s) {', '.join(unknown)}", path=path, field="config")
        try:
            return cls(**config)
        except TypeError as exc:
            raise InputError(str(exc), path=path, field="config") from None
