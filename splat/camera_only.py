"""Seeds for what the camera sees and the LiDAR never reached: triangles at sparse image points.

Outdoors the camera sees sky and structure above the LiDAR's field (building tops, tree crowns,
an overpass) and beyond its range; the warm-start mesh has no triangle there, so training could
only paint the background's colour. The keyframes' triangulated feature points
(``SCENE_DIR/sparse_points.ply``, :mod:`slam_bridge.sparse_points`) reach those surfaces. Each
point no LiDAR return explains becomes one small triangle facing the keyframe that sees it best,
as large as the gaps to its neighbouring points (the size rule of splatting's SfM
initialisation); training then moves, densifies or prunes them like any other triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

#: A sparse point is explained by the LiDAR when a return lies within this distance of it: the
#: larger of an absolute floor and a fraction of its distance from the nearest camera (the
#: triangulation's error grows with depth).
EXPLAINED_MIN_M = 0.3
EXPLAINED_FRACTION = 0.03
#: Neighbours whose mean distance sizes a seed, and its bounds as a fraction of its depth.
SIZE_NEIGHBOURS = 3
SIZE_MIN_FRACTION = 0.005
SIZE_MAX_FRACTION = 0.05


@dataclass(frozen=True)
class CameraOnlySeeds:
    """Triangles ``(S, 3, 3)`` and their colours ``(S, 3, 3)`` in [0, 1] at the ``S`` sparse points
    no LiDAR return explains, of ``n_points`` in all."""

    triangles: np.ndarray
    colors: np.ndarray
    n_points: int

    @property
    def reason(self) -> str:
        return (
            f"{len(self.triangles)} camera-only triangles seeded at the sparse points no LiDAR return "
            f"explains ({len(self.triangles)} of {self.n_points})"
        )


def unexplained_points(points: np.ndarray, lidar: np.ndarray, camera_centres: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: the sparse points ``(N, 3)`` with no LiDAR point of ``lidar`` ``(M, 3)`` within
    max(:data:`EXPLAINED_MIN_M`, :data:`EXPLAINED_FRACTION` × their distance to the nearest camera
    centre of ``camera_centres`` ``(K, 3)``)."""
    depth = cKDTree(camera_centres).query(points)[0]
    radius = np.maximum(EXPLAINED_MIN_M, EXPLAINED_FRACTION * depth)
    if len(lidar) == 0:
        return np.ones(len(points), dtype=bool)
    nearest = cKDTree(lidar).query(points, distance_upper_bound=float(radius.max()) + 1e-9)[0]
    return nearest > radius


def facing_triangles(points: np.ndarray, normals: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Equilateral triangles ``(N, 3, 3)`` centred on ``points`` ``(N, 3)`` in the planes of unit
    ``normals`` ``(N, 3)``, with circumradii ``radii`` ``(N,)``."""
    helper = np.where(np.abs(normals[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(normals, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(normals, u)
    angles = 2.0 * np.pi * np.arange(3) / 3.0
    offsets = np.cos(angles)[None, :, None] * u[:, None] + np.sin(angles)[None, :, None] * v[:, None]
    return points[:, None, :] + radii[:, None, None] * offsets


def camera_only_seeds(
    points: np.ndarray, colors: np.ndarray, lidar: np.ndarray, camera_centres: np.ndarray
) -> CameraOnlySeeds:
    """One triangle at each sparse point ``(N, 3)`` (RGB ``(N, 3)`` uint8) that ``lidar`` ``(M, 3)``
    does not explain (:func:`unexplained_points`), facing its nearest of ``camera_centres``
    ``(K, 3)``, its circumradius the mean distance to its :data:`SIZE_NEIGHBOURS` nearest sparse
    points within [:data:`SIZE_MIN_FRACTION`, :data:`SIZE_MAX_FRACTION`] of its depth."""
    keep = unexplained_points(points, lidar, camera_centres)
    empty = np.zeros((0, 3, 3))
    if keep.sum() == 0:
        return CameraOnlySeeds(empty, empty, len(points))
    chosen = points[keep]
    depth, nearest_camera = cKDTree(camera_centres).query(chosen)
    towards = camera_centres[nearest_camera] - chosen
    normals = towards / np.maximum(np.linalg.norm(towards, axis=1, keepdims=True), 1e-12)
    k = min(SIZE_NEIGHBOURS, len(points) - 1)
    if k > 0:
        gaps = cKDTree(points).query(chosen, k=k + 1)[0][:, 1:].mean(axis=1)
    else:
        gaps = SIZE_MAX_FRACTION * depth
    radii = np.clip(gaps, SIZE_MIN_FRACTION * depth, SIZE_MAX_FRACTION * depth)
    rgb = np.repeat((colors[keep] / 255.0)[:, None, :], 3, axis=1)
    return CameraOnlySeeds(facing_triangles(chosen, normals, radii), rgb, len(points))
