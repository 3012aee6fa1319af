"""COLMAP sparse points for a keyframe scene, triangulated with pycolmap from the known poses.

SIFT matches between keyframes (:mod:`slam_bridge.colmap_matches`) are triangulated from the
keyframe poses: SfM from scratch fails on sparse, outward-facing robot trajectories (on a
virtual-rig room it registered 2 of 41 keyframes). The points seed the photometric-only TS+
baseline's Delaunay initialisation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.errors import InputError
from rig.transforms import invert
from slam_bridge.colmap_matches import quiet_colmap_log
from slam_bridge.scene import Keyframe


@dataclass(frozen=True)
class SparseResult:
    """Triangulated points ``(N, 3)`` with colours ``(N, 3)`` uint8 and their mean reprojection error."""

    points: np.ndarray
    colors: np.ndarray
    reprojection_error_px: float


def triangulate_keyframes(
    database: Path, images_dir: Path, workspace: Path, keyframes: list[Keyframe]
) -> SparseResult:
    """Triangulate the matches in ``database`` (see :func:`~slam_bridge.colmap_matches.match_keyframes`)
    of the images ``images_dir/NAME.png`` from the keyframes' poses, which stay fixed; COLMAP's
    model is written to ``workspace``."""
    import pycolmap

    quiet_colmap_log()
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
    points = np.array([p.xyz for p in model.points3D.values()])
    colors = np.array([p.color for p in model.points3D.values()], dtype=np.uint8)
    return SparseResult(points, colors, float(model.compute_mean_reprojection_error()))
