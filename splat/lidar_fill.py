"""LiDAR returns the warm start misses, filled with one small triangle each.

A mapper's mesh does not cover every return its keyframes recorded: a TSDF needs several
consistent observations of a voxel, so facades seen at a grazing angle and the far road between
a spinning LiDAR's widening rings come out as holes, and simplifying the mesh to the training
budget opens more. On the virtual street a third of the training keyframes' returns lay more than
10 cm from the warm start, and those pixels rendered black. Each voxel of such returns that
enough keyframes hold gets one triangle in the plane of its neighbouring returns (open3d's
normals), as large as the gaps to its neighbours; training then treats it like a warm-start face.
Far away the voxels grow with the range: the returns of successive sweeps spread apart there, and
at one fixed size too few keyframes shared a voxel to fill the far road ahead.

The keyframe count keeps vehicles out: a car the moving-point detection missed (one driving
ahead at the robot's speed is seldom seen through) leaves its returns at a new place in every
sweep, so a voxel of it is held by the one or two keyframes whose windows share that sweep, while
the mapper's TSDF had already carved it away. Without the count, the fill put 450 m² of
triangles inside the virtual street's vehicles' swept volumes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from rig.mesh_rays import mesh_raycaster
from rig.open3d_lite import o3d
from splat.camera_only import explained_radius, facing_triangles

#: A return is explained by the warm start within the larger of this distance (m) and this
#: fraction of its range from the nearest camera.
EXPLAINED_MIN_M = 0.1
EXPLAINED_FRACTION = 0.02
#: Unexplained returns are thinned to one per voxel of this side (m), kept where at least
#: MIN_KEYFRAMES keyframes hold one in the voxel (neighbouring keyframes share a sweep).
VOXEL_M = 0.25
MIN_KEYFRAMES = 3
#: Beyond VOXEL_M / VOXEL_FRACTION metres from the nearest camera the voxel grows with the range,
#: in steps of 2 (a spinning LiDAR's rings and returns spread apart with it): at most MAX_LEVELS.
VOXEL_FRACTION = 0.01
MAX_LEVELS = 2
#: Returns whose plane is estimated from this many neighbours within this many voxels.
NORMAL_NEIGHBOURS = 16
NORMAL_RADIUS_VOXELS = 4.0
#: A triangle's circumradius: the mean distance to its nearest filled neighbours times this
#: (equilateral triangles of the gap's radius leave gaps between them), within [1, 3] voxels.
SIZE_NEIGHBOURS = 3
SIZE_FACTOR = 1.5


@dataclass(frozen=True)
class LidarFill:
    """Triangles ``(T, 3, 3)`` at the ``T`` voxels of the ``n_unexplained`` of ``n_returns`` LiDAR
    returns that no warm-start face lies near, of ``n_voxels`` voxels (the others held by fewer
    than :data:`MIN_KEYFRAMES` keyframes)."""

    triangles: np.ndarray
    n_unexplained: int
    n_returns: int
    n_voxels: int

    @property
    def reason(self) -> str:
        share = self.n_unexplained / max(self.n_returns, 1)
        return (
            f"{len(self.triangles)} triangles fill the LiDAR returns the warm start misses "
            f"({100 * share:.1f} % of {self.n_returns}, in {self.n_voxels} voxels of {VOXEL_M:g}–"
            f"{VOXEL_M * 2**MAX_LEVELS:g} m by range; "
            f"{self.n_voxels - len(self.triangles)} held by fewer than {MIN_KEYFRAMES} keyframes left out)"
        )


def unexplained_returns(mesh: trimesh.Trimesh, points: np.ndarray, camera_centres: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: the returns ``points`` ``(N, 3)`` farther from ``mesh`` than their
    :func:`~splat.camera_only.explained_radius` of max(:data:`EXPLAINED_MIN_M`,
    :data:`EXPLAINED_FRACTION` × their distance to the nearest of ``camera_centres`` ``(K, 3)``)."""
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    if len(mesh.faces) == 0:
        return np.ones(len(points), dtype=bool)
    raycaster = mesh_raycaster(mesh)
    distance = raycaster.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()
    return distance > explained_radius(points, camera_centres, EXPLAINED_MIN_M, EXPLAINED_FRACTION)


def voxel_levels(points: np.ndarray, camera_centres: np.ndarray) -> np.ndarray:
    """``(N,)`` int: each point's voxel level (side ``VOXEL_M · 2**level``) by its range from the
    nearest of ``camera_centres`` ``(K, 3)``: the level whose side is nearest below
    :data:`VOXEL_FRACTION` of it, within [0, :data:`MAX_LEVELS`]."""
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    distance = cKDTree(camera_centres).query(points)[0]
    ratio = np.maximum(VOXEL_FRACTION * distance / VOXEL_M, 1.0)
    return np.clip(np.floor(np.log2(ratio)), 0, MAX_LEVELS).astype(np.int64)


def _held_voxels(
    points: np.ndarray, keyframe: np.ndarray, level: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int]:
    """One point ``(V, 3)`` per voxel of ``points`` ``(N, 3)`` (the mean of the voxel's points; side
    ``VOXEL_M · 2**level`` by each point's ``level`` ``(N,)``) that at least
    :data:`MIN_KEYFRAMES` distinct ``keyframe`` ids ``(N,)`` hold, the sides of those voxels ``(V,)``,
    and the number of voxels ``points`` occupy."""
    side = VOXEL_M * 2.0**level
    keys = np.column_stack([np.floor(points / side[:, None]).astype(np.int64), level])
    _, voxel, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    voxel = voxel.ravel()
    pairs = np.unique(np.column_stack([voxel, keyframe]), axis=0)
    held = np.bincount(pairs[:, 0], minlength=len(count)) >= MIN_KEYFRAMES
    sums = np.stack(
        [np.bincount(voxel, weights=points[:, i], minlength=len(count)) for i in range(3)], axis=1
    )
    voxel_side = np.bincount(voxel, weights=side, minlength=len(count)) / count
    return (sums / count[:, None])[held], voxel_side[held], len(count)


def lidar_fill(
    mesh: trimesh.Trimesh, keyframe_points: list[np.ndarray], camera_centres: np.ndarray
) -> LidarFill:
    """One triangle per voxel (:data:`VOXEL_M`, larger at range: :func:`voxel_levels`) of the
    keyframes' LiDAR returns ``keyframe_points``
    (world ``(N_k, 3)`` each) that ``mesh`` does not explain (:func:`unexplained_returns`; cameras at
    ``camera_centres`` ``(K, 3)``) and that :data:`MIN_KEYFRAMES` keyframes hold, in the plane of
    the neighbouring voxels, its circumradius :data:`SIZE_FACTOR` times the mean gap to its
    :data:`SIZE_NEIGHBOURS` nearest voxels."""
    points = np.concatenate(keyframe_points) if keyframe_points else np.zeros((0, 3))
    keyframe = np.repeat(np.arange(len(keyframe_points)), [len(p) for p in keyframe_points])
    unexplained = unexplained_returns(mesh, points, camera_centres)
    level = voxel_levels(points[unexplained], camera_centres)
    centres, side, n_voxels = _held_voxels(points[unexplained], keyframe[unexplained], level)
    if len(centres) < SIZE_NEIGHBOURS + 1:
        return LidarFill(np.zeros((0, 3, 3)), int(unexplained.sum()), len(points), n_voxels)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(centres))
    normals = np.zeros_like(centres)
    for voxel in np.unique(side):  # each level's normals from neighbours as far apart as its voxels
        radius = NORMAL_RADIUS_VOXELS * voxel
        cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=NORMAL_NEIGHBOURS))
        normals[side == voxel] = np.asarray(cloud.normals)[side == voxel]
    gaps = cKDTree(centres).query(centres, k=SIZE_NEIGHBOURS + 1)[0][:, 1:].mean(axis=1)
    radii = np.clip(SIZE_FACTOR * gaps, side, 3 * side)
    return LidarFill(facing_triangles(centres, normals, radii), int(unexplained.sum()), len(points), n_voxels)
