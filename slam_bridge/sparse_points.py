"""COLMAP sparse points (and optional bundle-adjusted poses) for a keyframe scene, with pycolmap.

SIFT features are matched between keyframes and triangulated from the *known* poses (the LiDAR
trajectory): SfM from scratch fails on sparse, outward-facing robot trajectories (on a virtual-rig
room it registered 2 of 41 keyframes). The points seed the photometric-only TS+ baseline's Delaunay
initialisation. Optional bundle adjustment refines poses and points with the intrinsics fixed; the
result is then aligned back onto the LiDAR poses (similarity fit on camera centres) so the world
frame and metric scale stay the LiDAR's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError
from rig.transforms import invert, make_transform
from slam_bridge.scene import Keyframe

#: Above this many keyframes, match each only with its neighbours in time (sequential matching).
EXHAUSTIVE_MATCHING_LIMIT = 100


@dataclass(frozen=True)
class SparseResult:
    """Triangulated points ``(N, 3)`` with colours ``(N, 3)`` uint8, their mean reprojection error,
    and the keyframe poses ``T_world_cam`` by name (refined if asked, else the given ones)."""

    points: np.ndarray
    colors: np.ndarray
    reprojection_error_px: float
    poses: dict[str, np.ndarray]


def _similarity(source: np.ndarray, target: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Scale, rotation ``(3, 3)`` and translation ``(3,)`` with ``s R source + t ≈ target`` (Umeyama)."""
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    a, b = source - mu_s, target - mu_t
    U, S, Vt = np.linalg.svd(b.T @ a / len(a))
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    scale = float(np.trace(np.diag(S) @ D) / (a**2).sum(axis=1).mean())
    return scale, R, mu_t - scale * R @ mu_s


def triangulate_keyframes(
    images_dir: Path,
    workspace: Path,
    camera: CameraModel,
    keyframes: list[Keyframe],
    refine_poses: bool = False,
) -> SparseResult:
    """Features, matches and triangulation of the keyframe images ``images_dir/NAME.png``.

    Args:
        workspace: folder for COLMAP's database and model (created).
        camera: the distortion-free pinhole camera of the images (kept fixed).
        refine_poses: run a bundle adjustment of poses and points (intrinsics fixed).
    """
    import pycolmap

    workspace.mkdir(parents=True, exist_ok=True)
    database = workspace / "database.db"
    database.unlink(missing_ok=True)
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    reader.camera_params = f"{camera.fx},{camera.fy},{camera.cx},{camera.cy}"
    names = [f"{k.name}.png" for k in keyframes]
    pycolmap.extract_features(
        database,
        images_dir,
        image_names=names,
        camera_mode=pycolmap.CameraMode.SINGLE,
        reader_options=reader,
        device=pycolmap.Device.cpu,
    )
    if len(names) <= EXHAUSTIVE_MATCHING_LIMIT:
        pycolmap.match_exhaustive(database, device=pycolmap.Device.cpu)
    else:
        pycolmap.match_sequential(database, device=pycolmap.Device.cpu)

    given = {f"{k.name}.png": k.T_world_cam for k in keyframes}
    db = pycolmap.Database.open(database)
    try:
        cameras, rigs, frames = db.read_all_cameras(), db.read_all_rigs(), db.read_all_frames()
        images = {image.image_id: image for image in db.read_all_images()}
    finally:
        db.close()
    reconstruction = pycolmap.Reconstruction()
    for item in cameras:
        reconstruction.add_camera(item)
    for rig in rigs:
        reconstruction.add_rig(rig)
    for frame in frames:
        image = images[next(iter(frame.data_ids)).id]
        T_cam_world = invert(given[image.name])
        frame.rig_from_world = pycolmap.Rigid3d(pycolmap.Rotation3d(T_cam_world[:3, :3]), T_cam_world[:3, 3])
        reconstruction.add_frame(frame)
    for image in images.values():
        reconstruction.add_image(image)
    for frame in frames:
        reconstruction.register_frame(frame.frame_id)
    model = pycolmap.triangulate_points(reconstruction, database, images_dir, workspace)
    if model.num_points3D() == 0:
        raise InputError("COLMAP triangulated no points: too little texture or overlap", path=images_dir)

    if refine_poses:
        options = pycolmap.BundleAdjustmentOptions()
        options.refine_focal_length = False
        options.refine_principal_point = False
        options.refine_extra_params = False
        pycolmap.bundle_adjustment(model, options)
        centres = np.array([model.find_image_with_name(n).projection_center() for n in names])
        scale, R, t = _similarity(centres, np.array([given[n][:3, 3] for n in names]))
        model.transform(pycolmap.Sim3d(scale, pycolmap.Rotation3d(R), t))

    poses = {}
    for name in names:
        cam_from_world = model.find_image_with_name(name).cam_from_world()
        T_cam_world = make_transform(cam_from_world.rotation.matrix(), cam_from_world.translation)
        poses[name[: -len(".png")]] = invert(T_cam_world)
    points = np.array([p.xyz for p in model.points3D.values()])
    colors = np.array([p.color for p in model.points3D.values()], dtype=np.uint8)
    return SparseResult(points, colors, float(model.compute_mean_reprojection_error()), poses)
