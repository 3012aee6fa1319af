"""Leaned views: test poses turned and shifted slightly off the trajectory, where photometric-only
splatting leaves holes that the training views never showed.

A hole is a pixel where the ground truth has a surface but the reconstruction does not (for a
mesh: its ray hits nothing; for a splat model: accumulated alpha < 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from rig.camera import CameraModel
from rig.mesh_rays import cast_camera_rays, mesh_raycaster, pixel_rays
from rig.transforms import make_transform

#: A model's pixel with less accumulated opacity than this shows no surface (a hole).
ALPHA_SURFACE = 0.5
#: Ground-truth surface beyond this range along a pixel's ray is not scored.
MAX_RANGE_M = 20.0


def leaned_poses(poses_world_cam: np.ndarray, yaw_deg: float = 10.0, shift_m: float = 0.2) -> np.ndarray:
    """Four leaned variants ``(4N, 4, 4)`` of each camera pose ``(N, 4, 4)``: turned by ±``yaw_deg``
    about the camera's vertical (y) axis and shifted by ±``shift_m`` along its x axis."""
    turn = Rotation.from_euler("y", [[yaw_deg], [-yaw_deg]], degrees=True).as_matrix()
    offsets = [make_transform(R, np.zeros(3)) for R in turn]
    offsets += [make_transform(np.eye(3), [s, 0.0, 0.0]) for s in (shift_m, -shift_m)]
    return np.stack([pose @ offset for pose in np.asarray(poses_world_cam) for offset in offsets])


def hit_mask(
    scene, camera: CameraModel, T_world_cam: np.ndarray, max_range_m: float = MAX_RANGE_M
) -> np.ndarray:
    """``(H, W)`` bool: which pixels of a camera at ``T_world_cam`` see a surface of ``scene`` (a
    :func:`rig.mesh_rays.mesh_raycaster`) within ``max_range_m`` along the ray."""
    t_hit = cast_camera_rays(scene, T_world_cam, pixel_rays(camera))["t_hit"]
    return (t_hit <= max_range_m).reshape(camera.height, camera.width)


@dataclass(frozen=True)
class HoleResult:
    """Fraction of ground-truth surface pixels that are holes, over all views, and per-view masks
    ``(V, H, W)`` of the holes (for pictures)."""

    hole_fraction: float
    holes: np.ndarray


def mesh_hole_fraction(
    reconstruction: trimesh.Trimesh,
    ground_truth: trimesh.Trimesh,
    camera: CameraModel,
    poses_world_cam: np.ndarray,
    max_range_m: float = MAX_RANGE_M,
) -> HoleResult:
    """Holes of a reconstructed mesh seen from ``poses_world_cam`` ``(V, 4, 4)`` (e.g. leaned ones)."""
    rec, gt = mesh_raycaster(reconstruction), mesh_raycaster(ground_truth)
    holes, surface = [], 0
    for pose in np.asarray(poses_world_cam):
        gt_hit = hit_mask(gt, camera, pose, max_range_m)
        holes.append(gt_hit & ~hit_mask(rec, camera, pose, max_range_m))
        surface += int(gt_hit.sum())
    stacked = np.stack(holes)
    return HoleResult(float(stacked.sum() / surface) if surface else 0.0, stacked)
