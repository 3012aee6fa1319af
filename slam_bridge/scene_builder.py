"""``lts prepare``: keyframes with poses, undistorted images, LiDAR points and normal priors.

:func:`build_scene` runs the steps in order: keyframe selection and poses
(:mod:`slam_bridge.keyframe_selection`), images, optional matching (pose refinement, sparse
points), keyframe LiDAR (:mod:`slam_bridge.keyframe_lidar`) and normals
(:mod:`slam_bridge.keyframe_normals`), then the index (:mod:`slam_bridge.scene`).
"""

from __future__ import annotations

import logging
import shutil
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import cv2
import numpy as np
import trimesh

from rig.calibration import Calibration
from rig.camera import CameraModel
from rig.errors import InputError
from rig.mesh_rays import mesh_raycaster
from rig.messages import Frame
from rig.session import Recording, as_recording, find_topics
from slam_bridge.colmap_matches import (
    KeyframeDatabase,
    MatchingReport,
    Progress,
    extract_keyframe_features,
    match_keyframes,
    read_correspondences,
)
from slam_bridge.guided_matching import REFINEMENT_TOLERANCE_DEG, TOLERANCE_DEG
from slam_bridge.keyframe_lidar import keyframe_lidar, write_keyframe_lidar
from slam_bridge.keyframe_normals import write_keyframe_normals
from slam_bridge.keyframe_selection import (
    camera_poses,
    default_interval,
    describe_spacing,
    frame_stamps,
    make_keyframes,
    select_keyframes,
)
from slam_bridge.pose_refinement import RefinementReport, refine_keyframe_poses
from slam_bridge.prepare_config import PrepareConfig
from slam_bridge.scene import SPARSE_POINTS_FILE, Keyframe, write_scene_index
from slam_bridge.slam_dir import MESH_FILE, load_slam_dir
from slam_bridge.sparse_points import triangulate_keyframes

log = logging.getLogger(__name__)
DEFAULT_CONFIG = PrepareConfig()


@dataclass(frozen=True)
class SceneBuild:
    """What :func:`build_scene` wrote: the keyframes and, with ``refine_poses``, the refinement's
    report; with ``sparse_points`` or ``refine_poses``, matching's (with both, that of the matching
    at the final poses the sparse points come from); with ``sparse_points``, the seconds
    triangulation took; the seconds between keyframes (as given, or the default's)."""

    keyframes: list[Keyframe]
    refinement: RefinementReport | None
    matching: MatchingReport | None
    triangulation_s: float | None
    interval_s: float
    spacing: str

    def matching_summary(self) -> str | None:
        """One line on matching and triangulation (None when neither ran)."""
        m = self.matching
        if m is None:
            return None
        line = (
            f"matching: {m.keypoints_mean:.0f} keypoints per keyframe, {m.matched_pairs} of {m.pairs} "
            f"keyframe pairs matched, {m.matches} matches; features {m.extraction_s:.1f} s, "
            f"pairs {m.pairing_s:.1f} s, matching {m.matching_s:.1f} s"
        )
        return line if self.triangulation_s is None else f"{line}, triangulation {self.triangulation_s:.1f} s"


def build_scene(
    session: Recording | str | Path,
    calibration: Calibration,
    slam_dir: str | Path,
    out_dir: str | Path,
    config: PrepareConfig = DEFAULT_CONFIG,
    progress: Progress | None = None,
) -> SceneBuild:
    """Write the scene folder (see :mod:`slam_bridge.scene`); ``progress(step, done, total)`` is
    called after each keyframe's image, LiDAR points and normal prior (step ``"keyframes"``) and
    as matching goes (:func:`~slam_bridge.colmap_matches.match_keyframes`). ``session``: an open
    recording (its topic map and time span apply) or its path."""
    reader = as_recording(session)
    topics = find_topics(reader, config.image_topic, config.points_topic)
    mesh, trajectory = load_slam_dir(slam_dir)
    out, target = Path(out_dir), config.scene_camera(calibration.camera)
    frame_t = frame_stamps(reader, topics.image)
    if config.keyframe_interval_s is None:
        config = replace(config, keyframe_interval_s=default_interval(frame_t, trajectory, calibration))
    interval, motion, travel = (
        config.keyframe_interval_s,
        config.keyframe_min_motion,
        config.keyframe_max_travel_m,
    )
    chosen = select_keyframes(frame_t, trajectory, calibration, interval, motion, travel)
    keyframes = make_keyframes(
        frame_t[chosen], camera_poses(trajectory, calibration, frame_t[chosen]), config.test_every
    )
    if config.test_every and not any(k.split == "test" for k in keyframes):
        log.warning(
            "%d keyframes, none held out for testing (every %d-th is): lts eval will have no test view; "
            "take keyframes more often (--keyframe-interval) or hold out more (--test-every)",
            len(keyframes),
            config.test_every,
        )
    done = _counter(progress, 3 * len(keyframes))
    frames = reader.frames_at(topics.image, chosen)
    write_keyframe_images(out, frames, keyframes, calibration.camera, target, reader.path, done)
    raycaster = mesh_raycaster(mesh)
    database, matching, refinement = None, None, None
    if config.refine_poses or config.sparse_points:
        names = [f"{k.name}.png" for k in keyframes]
        database = extract_keyframe_features(out / "images", out / "colmap", target, names, progress)
    if config.refine_poses:
        matching = _matches(database, target, keyframes, raycaster, progress, REFINEMENT_TOLERANCE_DEG)
        keyframes, refinement = _refined(database.path, target, keyframes, raycaster)
    if config.sparse_points:  # matched (again) at the final poses, to the tolerance of right poses
        matching = _matches(database, target, keyframes, raycaster, progress, TOLERANCE_DEG)
    points = keyframe_lidar(
        reader.scans(topics.points), trajectory, calibration, keyframes, target, config.keyframe_interval_s
    )
    write_keyframe_lidar(out, keyframes, points, done)
    write_keyframe_normals(
        out, keyframes, chosen, calibration.camera, target, raycaster, config.normals_dir, done
    )
    shutil.copyfile(Path(slam_dir) / MESH_FILE, out / "mesh.ply")
    sparse_file, triangulation_s = None, None
    if config.sparse_points:
        started = time.perf_counter()
        sparse_file = _write_sparse_points(database.path, out, keyframes)
        triangulation_s = time.perf_counter() - started
    source = {
        "session": str(reader.path),
        "slam_dir": str(slam_dir),
        "pose_refinement": None if refinement is None else asdict(refinement),
        "matching": None if matching is None else asdict(matching),
        "triangulation_s": triangulation_s,
    }
    write_scene_index(out, target, keyframes, config, source, sparse_points=sparse_file)
    spacing = describe_spacing(frame_t[chosen], interval, motion, travel)
    return SceneBuild(keyframes, refinement, matching, triangulation_s, interval, spacing)


def _counter(progress: Progress | None, total: int) -> Callable[[], None]:
    """A callback that reports one more keyframe step of ``total`` to ``progress`` (if any) on each call."""
    steps = iter(range(1, total + 1))

    def done() -> None:
        step = next(steps)
        if progress is not None:
            progress("keyframes", step, total)

    return done


def write_keyframe_images(
    out: Path,
    frames: Iterable[Frame],
    keyframes: list[Keyframe],
    camera: CameraModel,
    target: CameraModel,
    session: Path,
    done: Callable[[], None],
) -> None:
    """Save each keyframe's frame (``frames``: one per keyframe, of the ``session``'s ``camera``)
    resampled into the scene's camera ``target`` (undistorted, area-averaged where smaller) as
    ``out/images/NAME.png``; ``done()`` after each."""
    (out / "images").mkdir(parents=True, exist_ok=True)
    for frame, keyframe in zip(frames, keyframes, strict=True):
        if (frame.width, frame.height) != (camera.width, camera.height):
            raise InputError(
                f"session images are {frame.width}x{frame.height} but the calibration's camera is "
                f"{camera.width}x{camera.height}",
                path=session,
                field="camera.width/height",
            )
        image = camera.undistort_image(frame.image, target, interpolation=cv2.INTER_AREA)
        cv2.imwrite(str(out / "images" / f"{keyframe.name}.png"), image)
        done()


def _matches(
    database: KeyframeDatabase,
    camera: CameraModel,
    keyframes: list[Keyframe],
    raycaster,
    progress: Progress | None,
    tolerance_deg: float,
) -> MatchingReport:
    """Match the keyframe images of ``database`` to ``tolerance_deg`` of the keyframes' poses (in
    place of earlier matches); the report."""
    poses = np.stack([k.T_world_cam for k in keyframes])
    return match_keyframes(database, camera, poses, raycaster, progress, tolerance_deg=tolerance_deg)


def _refined(
    database: Path, camera: CameraModel, keyframes: list[Keyframe], raycaster
) -> tuple[list[Keyframe], RefinementReport]:
    """The keyframes with poses refined against the SLAM mesh, and the refinement's report."""
    names = [k.name for k in keyframes]
    correspondences = read_correspondences(database, [f"{name}.png" for name in names])
    refined, report = refine_keyframe_poses(
        names,
        np.array([k.t_ns for k in keyframes]),
        np.stack([k.T_world_cam for k in keyframes]),
        camera,
        correspondences,
        raycaster,
    )
    return [replace(k, T_world_cam=T) for k, T in zip(keyframes, refined, strict=True)], report


def _write_sparse_points(database: Path, out: Path, keyframes: list[Keyframe]) -> str:
    """Triangulate the matches from the keyframe poses into ``out/sparse_points.ply``; its name."""
    sparse = triangulate_keyframes(database, out / "images", out / "colmap", keyframes)
    trimesh.PointCloud(sparse.points, colors=sparse.colors).export(out / SPARSE_POINTS_FILE)
    return SPARSE_POINTS_FILE
