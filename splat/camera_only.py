"""Seeds for what the camera sees and the LiDAR never reached: triangles at sparse image points.

Outdoors the camera sees sky and structure above the LiDAR's field (building tops, tree crowns,
an overpass) and beyond its range; the warm-start mesh has no triangle there, so training could
only paint the background's colour. The keyframes' triangulated feature points
(``SCENE_DIR/sparse_points.ply``, :mod:`slam_bridge.sparse_points`) reach those surfaces. Each
point that a keyframe sees above every LiDAR return of its image column (beyond the LiDAR's
field or range), that no return explains and that the LiDAR does not see through (a wrong
triangulation in front of a surface) becomes one small triangle facing the nearest keyframe,
as large as the gaps to its neighbouring points (the size rule of splatting's SfM
initialisation); training then moves, densifies or prunes them like any other triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.ndimage import minimum_filter
from scipy.spatial import cKDTree

from rig.camera import CameraModel
from rig.transforms import invert, transform_points
from splat.background_mask import above_lidar

#: A sparse point is explained by the LiDAR when a return lies within this distance of it: the
#: larger of an absolute floor and a fraction of its distance from the nearest camera (the
#: triangulation's error grows with depth).
EXPLAINED_MIN_M = 0.3
EXPLAINED_FRACTION = 0.03
#: A point that this many keyframes' LiDAR sees through (a return beyond it by the explained radius,
#: the nearest in a window of this many pixels) is a wrong triangulation, never a seed.
SEE_THROUGH_VOTES = 2
SEE_THROUGH_WINDOW_PX = 5
#: Neighbours whose mean distance sizes a seed, and its bounds as a fraction of its depth.
SIZE_NEIGHBOURS = 3
SIZE_MIN_FRACTION = 0.005
SIZE_MAX_FRACTION = 0.05


@dataclass(frozen=True)
class CameraOnlySeeds:
    """Triangles ``(S, 3, 3)`` and their colours ``(S, 3, 3)`` in [0, 1] at the ``S`` sparse points
    beyond the LiDAR's reach that no return explains or sees through, of ``n_points`` in all
    (``n_unexplained`` of them unexplained and beyond its reach)."""

    triangles: np.ndarray
    colors: np.ndarray
    n_points: int
    n_unexplained: int

    @property
    def reason(self) -> str:
        return (
            f"{len(self.triangles)} camera-only triangles seeded at sparse points: {self.n_unexplained} of "
            f"{self.n_points} lie above the LiDAR's reach with no return near them, "
            f"{self.n_unexplained - len(self.triangles)} of those the LiDAR sees through"
        )


def explained_radius(
    points: np.ndarray,
    camera_centres: np.ndarray,
    min_m: float = EXPLAINED_MIN_M,
    fraction: float = EXPLAINED_FRACTION,
) -> np.ndarray:
    """``(N,)`` max(``min_m``, ``fraction`` × the distance of each of ``points`` ``(N, 3)`` to the
    nearest of ``camera_centres`` ``(K, 3)``): how near a surface must lie to explain a point whose
    position error grows with its depth."""
    return np.maximum(min_m, fraction * cKDTree(camera_centres).query(points)[0])


def unexplained_points(points: np.ndarray, lidar: np.ndarray, camera_centres: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: the sparse points ``(N, 3)`` with no LiDAR point of ``lidar`` ``(M, 3)`` within
    their :func:`explained_radius` (cameras at ``camera_centres`` ``(K, 3)``)."""
    radius = explained_radius(points, camera_centres)
    if len(lidar) == 0:
        return np.ones(len(points), dtype=bool)
    nearest = cKDTree(lidar).query(points, distance_upper_bound=float(radius.max()) + 1e-9)[0]
    return nearest > radius


def seen_through(
    points: np.ndarray, camera: CameraModel, poses_world_cam: np.ndarray, depths: list[np.ndarray]
) -> np.ndarray:
    """``(N,)`` bool: the points ``(N, 3)`` that at least :data:`SEE_THROUGH_VOTES` keyframes (poses
    ``(K, 4, 4)``, LiDAR depth images ``(H, W)``, 0 = no return) see through: the nearest return
    within :data:`SEE_THROUGH_WINDOW_PX` of the point's pixel lies beyond it by more than the
    explained radius. Above the LiDAR's field there is no return, so nothing is seen through."""
    votes = np.zeros(len(points), dtype=np.int64)
    for T_world_cam, depth in zip(poses_world_cam, depths, strict=True):
        nearest = minimum_filter(np.where(depth > 0, depth, np.inf), size=SEE_THROUGH_WINDOW_PX)
        index, rows, cols, z = in_view(points, camera, T_world_cam)
        margin = np.maximum(EXPLAINED_MIN_M, EXPLAINED_FRACTION * z)
        beyond = nearest[rows, cols]
        votes[index] += np.isfinite(beyond) & (beyond > z + margin)
    return votes >= SEE_THROUGH_VOTES


def beyond_lidar_reach(
    points: np.ndarray, camera: CameraModel, poses_world_cam: np.ndarray, depths: list[np.ndarray]
) -> np.ndarray:
    """``(N,)`` bool: the points ``(N, 3)`` that some keyframe (poses ``(K, 4, 4)``, LiDAR depth
    images ``(H, W)``) sees above every LiDAR return of their image column
    (:func:`splat.background_mask.above_lidar`): beyond the LiDAR's field or range."""
    beyond = np.zeros(len(points), dtype=bool)
    for T_world_cam, depth in zip(poses_world_cam, depths, strict=True):
        above = above_lidar(torch.as_tensor(depth)).numpy()
        index, rows, cols, _ = in_view(points, camera, T_world_cam)
        beyond[index[above[rows, cols]]] = True
    return beyond


def in_view(
    points: np.ndarray, camera: CameraModel, T_world_cam: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Of world points ``(N, 3)``, those in the image of ``camera`` at ``T_world_cam`` ``(4, 4)``:
    their indices ``(M,)``, the rows and columns of their nearest pixels ``(M,)`` and their depths
    ``(M,)``."""
    in_camera = transform_points(invert(T_world_cam), points)
    pixels = camera.project(in_camera)
    inside = camera.in_image(pixels)
    cols, rows = np.round(pixels[inside]).astype(np.int64).T
    return np.flatnonzero(inside), rows, cols, in_camera[inside, 2]


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


def one_per_grid_square(centres: np.ndarray, cell_m: float) -> np.ndarray:
    """Sorted indices ``(M,)`` of one of ``centres`` ``(N, 3)`` per cube of side ``cell_m`` of a world
    grid (the first of each): where cells made from several keyframes overlap, one is kept."""
    _, first = np.unique(np.floor(centres / cell_m).astype(np.int64), axis=0, return_index=True)
    return np.sort(first)


def quad_triangles(quads: np.ndarray) -> np.ndarray:
    """The two triangles ``(2N, 3, 3)`` of each quadrilateral ``(N, 4, 3)`` (corners in order): all
    first halves, then all second halves."""
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def camera_only_seeds(
    points: np.ndarray,
    colors: np.ndarray,
    lidar: np.ndarray,
    camera: CameraModel,
    poses_world_cam: np.ndarray,
    depths: list[np.ndarray],
) -> CameraOnlySeeds:
    """One triangle at each sparse point ``(N, 3)`` (RGB ``(N, 3)`` uint8) that ``lidar`` ``(M, 3)``
    does not explain (:func:`unexplained_points`), that lies beyond the LiDAR's reach in a keyframe
    (``camera`` at ``poses_world_cam`` ``(K, 4, 4)`` with LiDAR depth images ``depths``;
    :func:`beyond_lidar_reach`) and that they do not see through (:func:`seen_through`), facing
    its nearest keyframe, its circumradius the mean distance to its
    :data:`SIZE_NEIGHBOURS` nearest sparse points within [:data:`SIZE_MIN_FRACTION`,
    :data:`SIZE_MAX_FRACTION`] of its depth."""
    camera_centres = poses_world_cam[:, :3, 3]
    unexplained = unexplained_points(points, lidar, camera_centres)
    unexplained[unexplained] = beyond_lidar_reach(points[unexplained], camera, poses_world_cam, depths)
    keep = unexplained.copy()
    keep[unexplained] = ~seen_through(points[unexplained], camera, poses_world_cam, depths)
    empty = np.zeros((0, 3, 3))
    if keep.sum() == 0:
        return CameraOnlySeeds(empty, empty, len(points), int(unexplained.sum()))
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
    return CameraOnlySeeds(facing_triangles(chosen, normals, radii), rgb, len(points), int(unexplained.sum()))
