"""Which pixels of a test image show a moving object, from a virtual-rig ground truth.

``lts sim`` writes each mover's shape (``movers/NAME.ply``, in its own frame) and its poses at the
camera frames (``movers/NAME.tum``, ground-truth world). A pixel shows a mover when the ray of the
true camera at that stamp meets a posed mover before the static scene. Scored photometry on the
remaining *static* pixels measures what a method can reconstruct of a scene with traffic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.ndimage import binary_dilation

from eval.ground_truth import GT_CAMERA_TRAJECTORY, GT_MESH
from rig.camera import CameraModel
from rig.mesh_io import load_mesh
from rig.mesh_rays import cast_camera_rays, mesh_raycaster, pixel_rays
from rig.trajectory_io import read_tum

MOVERS_DIR = "movers"
#: Mask edges are widened by this many pixels: the camera's anti-aliased edge pixels mix the mover
#: with what is behind it.
EDGE_PX = 2


def mover_names(gt_dir: Path) -> list[str]:
    """Names of the movers of a ground-truth folder (``movers/NAME.ply`` with ``NAME.tum``)."""
    folder = gt_dir / MOVERS_DIR
    return sorted(p.stem for p in folder.glob("*.ply") if p.with_suffix(".tum").is_file())


def moving_pixel_masks(gt_dir: Path, camera: CameraModel, t_ns: np.ndarray) -> list[np.ndarray]:
    """``(H, W)`` bool masks, one per stamp of ``t_ns`` ``(N,)``: the pixels of ``camera`` at its true
    pose (the camera trajectory of the ground-truth folder ``gt_dir``) whose first hit is one of its
    movers rather than its static mesh, widened by :data:`EDGE_PX`."""
    names = mover_names(gt_dir)
    static = mesh_raycaster(load_mesh(gt_dir / GT_MESH))
    shapes = [load_mesh(gt_dir / MOVERS_DIR / f"{name}.ply") for name in names]
    tracks = [read_tum(gt_dir / MOVERS_DIR / f"{name}.tum") for name in names]
    camera_poses = read_tum(gt_dir / GT_CAMERA_TRAJECTORY).interpolate(t_ns, clamp=True)
    rays = pixel_rays(camera)
    masks = []
    for i, T_world_cam in enumerate(camera_poses):
        static_t = cast_camera_rays(static, T_world_cam, rays)["t_hit"]
        moving = np.zeros(len(rays), dtype=bool)
        for shape, track in zip(shapes, tracks, strict=True):
            if not track.covers(t_ns[i]):
                continue
            posed = shape.copy().apply_transform(track.interpolate(t_ns[i]))
            mover_t = cast_camera_rays(mesh_raycaster(posed), T_world_cam, rays)["t_hit"]
            moving |= mover_t < static_t
        mask = moving.reshape(camera.height, camera.width)
        masks.append(binary_dilation(mask, iterations=EDGE_PX) if mask.any() else mask)
    return masks
