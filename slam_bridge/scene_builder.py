"""``lts prepare``: keyframes with poses, undistorted images, LiDAR depth and normal priors."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np
import trimesh

from rig.calibration import Calibration
from rig.camera import CameraModel
from rig.errors import InputError
from rig.mesh_rays import cast_camera_rays, mesh_raycaster
from rig.messages import Frame, Scan
from rig.session import SessionReader, find_topics
from rig.trajectory import Trajectory
from rig.transforms import invert
from slam_bridge.colmap_matches import match_keyframes, read_correspondences
from slam_bridge.depth_image import remove_occluded, zbuffer_depth
from slam_bridge.pose_refinement import RefinementReport, refine_keyframe_poses
from slam_bridge.scene import SPARSE_POINTS_FILE, Keyframe, write_scene_index
from slam_bridge.slam_dir import MESH_FILE, load_slam_dir
from slam_bridge.sparse_points import triangulate_keyframes


@dataclass(frozen=True)
class PrepareConfig:
    """Settings of the scene builder.

    Attributes:
        keyframe_interval_s: one keyframe per this many seconds of camera frames (paper: ~0.5 s).
        keyframe_min_motion: ``(metres, degrees)``: choose keyframes by motion instead of time.
        test_every: every n-th keyframe is held out for testing.
        occlusion_window_px: window of the see-through test on LiDAR depth (0 disables it).
        image_topic, points_topic: choose topics when a session has several.
        normals_dir: a folder of precomputed normal maps (e.g. from a monocular normal network) to
            use instead of the SLAM mesh's normals: see :func:`read_normal_map`.
        sparse_points: triangulate COLMAP sparse points from the keyframes (for the TS+ baseline).
        refine_poses: refine the keyframe poses against the SLAM mesh, guarded by held-out
            matches (:mod:`slam_bridge.pose_refinement`); depth, normals and sparse points then
            use the refined poses.
    """

    keyframe_interval_s: float = 0.5
    keyframe_min_motion: tuple[float, float] | None = None
    test_every: int = 8
    occlusion_window_px: int = 7
    image_topic: str | None = None
    points_topic: str | None = None
    normals_dir: Path | None = None
    sparse_points: bool = False
    refine_poses: bool = False


def camera_poses(trajectory: Trajectory, calibration: Calibration, t_cam_ns: np.ndarray) -> np.ndarray:
    """``T_world_cam`` ``(N, 4, 4)`` at camera stamps ``(N,)``: the LiDAR trajectory at the LiDAR
    time of each frame (camera time − ``time_offset_s``) composed with ``T_lidar_cam``."""
    t_lidar = np.asarray(t_cam_ns, dtype=np.int64) - round(calibration.time_offset_s * 1e9)
    return trajectory.interpolate(t_lidar) @ invert(calibration.T_cam_lidar)


def select_keyframes(
    frame_t_ns: np.ndarray,
    trajectory: Trajectory,
    calibration: Calibration,
    interval_s: float,
    min_motion: tuple[float, float] | None = None,
) -> np.ndarray:
    """Indices of camera frames to keep, only where the trajectory covers them: one per
    ``interval_s``, or — with ``min_motion = (metres, degrees)`` — the next frame whose camera has
    moved or turned at least that much since the last keyframe."""
    t_lidar = frame_t_ns - round(calibration.time_offset_s * 1e9)
    covered = np.flatnonzero(trajectory.covers(t_lidar))
    if covered.size == 0:
        raise InputError(
            "the trajectory covers none of the camera frames (check time_offset_s and the SLAM folder)",
            field="trajectory",
        )
    poses = camera_poses(trajectory, calibration, frame_t_ns[covered]) if min_motion else None
    chosen = [0]
    for j in range(1, len(covered)):
        if poses is None:
            keep = (frame_t_ns[covered[j]] - frame_t_ns[covered[chosen[-1]]]) * 1e-9 >= interval_s - 1e-6
        else:
            relative = invert(poses[chosen[-1]]) @ poses[j]
            angle = np.degrees(np.arccos(np.clip((np.trace(relative[:3, :3]) - 1) / 2, -1.0, 1.0)))
            keep = np.linalg.norm(relative[:3, 3]) >= min_motion[0] or angle >= min_motion[1]
        if keep:
            chosen.append(j)
    return covered[np.asarray(chosen)]


#: Point times are rounded to this step (ns) before poses are interpolated: 0.1 ms moves a point by
#: 0.1 mm at 1 m/s and needs ~1000 poses per sweep instead of one per point.
DESKEW_STEP_NS = 100_000


def deskewed_world_points(scan: Scan, trajectory: Trajectory) -> np.ndarray:
    """World points ``(N, 3)`` of a scan, each moved by the trajectory pose at its own time (to
    :data:`DESKEW_STEP_NS`; clamped at the trajectory's ends)."""
    steps, index = np.unique(scan.point_times_ns(host=True) // DESKEW_STEP_NS, return_inverse=True)
    poses = trajectory.interpolate(steps * DESKEW_STEP_NS, clamp=True)[index]
    points = scan.points.astype(np.float64)
    return np.einsum("nij,nj->ni", poses[:, :3, :3], points) + poses[:, :3, 3]


def normal_prior(
    raycaster, T_world_cam: np.ndarray, rays_cam: np.ndarray, shape: tuple[int, int]
) -> np.ndarray:
    """Camera-frame normals ``(H, W, 3)`` of the mesh seen through each pixel ray (facing the camera)."""
    hits = cast_camera_rays(raycaster, T_world_cam, rays_cam)
    hit = np.isfinite(hits["t_hit"])
    normals = hits["primitive_normals"] @ T_world_cam[:3, :3]  # to the camera frame
    facing = np.einsum("ij,ij->i", normals, rays_cam) > 0
    normals[facing] *= -1
    normals[~hit] = 0
    return normals.reshape(*shape, 3).astype(np.float32)


def read_normal_map(folder: Path, frame_index: int, t_ns: int, camera: CameraModel) -> np.ndarray:
    """A precomputed normal map ``(H, W, 3)`` for one camera frame, in the original (distorted) image.

    Looked up as ``<t_ns>.npy|.png`` (the frame's host stamp) or ``<frame_index:06d>.npy|.png``
    (its position in the image topic). ``.npy``: float camera-frame normals (OpenCV axes); ``.png``:
    8-bit RGB encoding ``(n + 1) / 2``. Zero vectors mean "no normal".
    """
    for stem in (str(t_ns), f"{frame_index:06d}"):
        for suffix in (".npy", ".png"):
            path = folder / f"{stem}{suffix}"
            if not path.is_file():
                continue
            if suffix == ".npy":
                normals = np.load(path).astype(np.float32)
            else:
                encoded = cv2.imread(str(path), cv2.IMREAD_COLOR)
                if encoded is None:
                    raise InputError("cannot read normal map", path=path)
                normals = cv2.cvtColor(encoded, cv2.COLOR_BGR2RGB).astype(np.float32) / 127.5 - 1.0
            if normals.shape != (camera.height, camera.width, 3):
                raise InputError(
                    f"normal map is {normals.shape}, expected ({camera.height}, {camera.width}, 3)", path=path
                )
            return normals
    raise InputError(
        f"no normal map for frame {frame_index} ({t_ns} ns): expected {t_ns}.npy or {frame_index:06d}.png",
        path=folder,
    )


def undistort_normals(normals: np.ndarray, camera: CameraModel, target: CameraModel) -> np.ndarray:
    """Resample a normal map ``(H, W, 3)`` into the undistorted camera (nearest pixel, so normals are
    not blended across edges) and re-normalise; empty pixels stay zero."""
    resampled = camera.undistort_image(normals, target, interpolation=cv2.INTER_NEAREST)
    norms = np.linalg.norm(resampled, axis=-1, keepdims=True)
    return np.divide(resampled, norms, out=np.zeros_like(resampled), where=norms > 1e-6).astype(np.float32)


@dataclass(frozen=True)
class SceneBuild:
    """What :func:`build_scene` wrote: the keyframes and, with ``refine_poses``, the refinement's report."""

    keyframes: list[Keyframe]
    refinement: RefinementReport | None


def build_scene(
    session: str | Path,
    calibration: Calibration,
    slam_dir: str | Path,
    out_dir: str | Path,
    config: PrepareConfig = PrepareConfig(),
    progress: Callable[[int, int], None] | None = None,
) -> SceneBuild:
    """Write the scene folder (see :mod:`slam_bridge.scene`); ``progress(done, total)`` is called
    after each image and each depth image."""
    reader = SessionReader(session)
    topics = find_topics(reader, config.image_topic, config.points_topic)
    mesh, trajectory = load_slam_dir(slam_dir)
    camera = calibration.camera
    target = camera.undistorted()
    out = Path(out_dir)
    for sub in ("images", "depth", "normals"):
        (out / sub).mkdir(parents=True, exist_ok=True)

    frames: list[Frame] = list(reader.frames(topics.image))
    if not frames:
        raise InputError(f"no images on {topics.image}", path=reader.path)
    if (frames[0].width, frames[0].height) != (camera.width, camera.height):
        raise InputError(
            f"session images are {frames[0].width}x{frames[0].height} but the calibration's camera is "
            f"{camera.width}x{camera.height}",
            path=reader.path,
            field="camera.width/height",
        )
    frame_t = np.array([f.t_host for f in frames], dtype=np.int64)
    chosen = select_keyframes(
        frame_t, trajectory, calibration, config.keyframe_interval_s, config.keyframe_min_motion
    )
    poses = camera_poses(trajectory, calibration, frame_t[chosen])
    total = 2 * len(chosen)
    keyframes = []
    for n, (index, T_world_cam) in enumerate(zip(chosen, poses, strict=True)):
        name = f"kf_{n:04d}"
        cv2.imwrite(str(out / "images" / f"{name}.png"), camera.undistort_image(frames[index].image, target))
        split = "test" if config.test_every and n % config.test_every == config.test_every - 1 else "train"
        keyframes.append(Keyframe(name, int(frame_t[index]), T_world_cam, split))
        if progress is not None:
            progress(n + 1, total)

    raycaster = mesh_raycaster(mesh)
    image_names = [f"{k.name}.png" for k in keyframes]
    needs_matches = config.sparse_points or config.refine_poses
    database = match_keyframes(out / "images", out / "colmap", target, image_names) if needs_matches else None
    refinement = None
    if database is not None and config.refine_poses:
        correspondences = read_correspondences(database, image_names)
        refined, refinement = refine_keyframe_poses(
            [k.name for k in keyframes], frame_t[chosen], poses, target, correspondences, raycaster
        )
        keyframes = [replace(k, T_world_cam=T) for k, T in zip(keyframes, refined, strict=True)]

    scans = list(reader.scans(topics.points))
    offset_ns = round(calibration.time_offset_s * 1e9)
    scan_t = np.array([s.t_host for s in scans], dtype=np.int64) + offset_ns  # on the camera clock
    u, v = np.meshgrid(np.arange(target.width), np.arange(target.height))
    rays_cam = target.unproject(np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))
    rays_cam /= np.linalg.norm(rays_cam, axis=1, keepdims=True)

    @lru_cache(maxsize=64)
    def world_points(scan_index: int) -> np.ndarray:  # neighbouring keyframes share most scans
        return deskewed_world_points(scans[scan_index], trajectory)

    for n, (index, keyframe) in enumerate(zip(chosen, keyframes, strict=True)):
        # LiDAR returns between the previous and the next keyframe, deskewed by the trajectory.
        lo = frame_t[chosen[n - 1]] if n > 0 else frame_t[index] - int(config.keyframe_interval_s * 1e9)
        hi = (
            frame_t[chosen[n + 1]]
            if n + 1 < len(chosen)
            else frame_t[index] + int(config.keyframe_interval_s * 1e9)
        )
        near = [i for i, t in enumerate(scan_t) if lo <= t <= hi]
        if near:
            world = np.concatenate([world_points(i) for i in near])
            T_cam_world = invert(keyframe.T_world_cam)
            depth = zbuffer_depth(world @ T_cam_world[:3, :3].T + T_cam_world[:3, 3], target)
            if config.occlusion_window_px:
                depth = remove_occluded(depth, config.occlusion_window_px)
        else:
            depth = np.zeros((target.height, target.width), dtype=np.float32)
        np.save(out / "depth" / f"{keyframe.name}.npy", depth)
        if config.normals_dir is not None:
            given = read_normal_map(Path(config.normals_dir), int(index), int(frame_t[index]), camera)
            normals = undistort_normals(given, camera, target)
        else:
            normals = normal_prior(raycaster, keyframe.T_world_cam, rays_cam, (target.height, target.width))
        np.save(out / "normals" / f"{keyframe.name}.npy", normals)
        if progress is not None:
            progress(len(chosen) + n + 1, total)
    shutil.copyfile(Path(slam_dir) / MESH_FILE, out / "mesh.ply")
    sparse_file = None
    if database is not None and config.sparse_points:
        sparse = triangulate_keyframes(database, out / "images", out / "colmap", keyframes)
        trimesh.PointCloud(sparse.points, colors=sparse.colors).export(out / SPARSE_POINTS_FILE)
        sparse_file = SPARSE_POINTS_FILE
    source = {
        "session": str(session),
        "slam_dir": str(slam_dir),
        "keyframe_interval_s": config.keyframe_interval_s,
        "pose_refinement": None if refinement is None else asdict(refinement),
    }
    write_scene_index(out, target, keyframes, source, sparse_points=sparse_file)
    return SceneBuild(keyframes, refinement)
