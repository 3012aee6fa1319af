"""Upright surfaces continued above the LiDAR's reach: camera-only triangles on facades and poles.

A spinning LiDAR's top beam (KITTI's HDL-64E: +2°) reaches a facade 16 m away about 2 m above
the sensor, while the camera sees it to the roof: most of a street image is wall that no return
touches, and the warm start ends in a ragged edge just below the topmost ring. Where the topmost
LiDAR return of an image column lies on an upright surface (its normal within
:data:`UPRIGHT_MAX_COS` of horizontal), that surface is continued straight up as a strip of square
cells, one column of :data:`COLUMN_PX` pixels wide, from one cell below the return to the top of
the image (at most :data:`MAX_HEIGHT_M` above the return). Cells the warm start hides from the
camera that made them (a wall continued past the ceiling) and cells that the LiDAR of a keyframe
sees through (a return beyond them: :func:`splat.camera_only.seen_through`) are dropped; those where
the wall in truth ended (sky or a farther building behind) are left to training, which makes them
transparent and prunes them, as it does with the sparse-point seeds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from rig.camera import CameraModel
from rig.mesh_rays import cast_world_rays, mesh_raycaster
from slam_bridge.scene import KeyframeLidar
from splat.camera_only import one_per_grid_square, quad_triangles, seen_through
from splat.plane_sweep import AGREE_FRACTION
from splat.upright_planes import UprightPlanes

#: Image columns are grouped this many pixels wide; each group's topmost return starts one strip,
#: whose cells are as wide as the group at the return's depth.
COLUMN_PX = 12
#: A return is on an upright surface when its normal's component along up is below this.
UPRIGHT_MAX_COS = 0.3
#: A strip rises at most this far above its return (m).
MAX_HEIGHT_M = 25.0
#: Returns nearer than this are not continued (m): the car's own body, a passer-by.
MIN_DEPTH_M = 2.0
#: A return's surface is the plane through the returns within this fraction of its depth, when
#: there are at least MIN_NEIGHBOURS of them and their least spread is below PLANARITY times the
#: next (a plane, not a bush or a corner).
NEIGHBOUR_FRACTION = 0.05
MIN_NEIGHBOURS = 8
PLANARITY = 0.1


@dataclass(frozen=True)
class UpwardExtension:
    """Two triangles per cell ``(2C, 3, 3)`` continuing ``n_strips`` upright surfaces above the
    LiDAR's reach, ``n_seen_through`` cells dropped because the LiDAR sees through them, and the
    surfaces' ``planes`` (one per strip, however many of its cells were kept)."""

    triangles: np.ndarray
    n_strips: int
    n_seen_through: int
    planes: UprightPlanes

    @property
    def reason(self) -> str:
        return (
            f"{len(self.triangles) // 2} camera-only cells continue {self.n_strips} upright surfaces above "
            f"the LiDAR's topmost returns ({self.n_seen_through} cells the LiDAR sees through left out)"
        )


def rise_to_image_top(points_cam: np.ndarray, up_cam: np.ndarray, camera: CameraModel) -> np.ndarray:
    """``(N,)`` metres along ``up_cam`` ``(3,)`` from camera-frame ``points_cam`` ``(N, 3)`` to the top
    image row (the rise of a pinhole row ``fy·y/z + cy`` to 0), :data:`MAX_HEIGHT_M` where the
    upward line never leaves the image's top."""
    y, z = points_cam[:, 1], points_cam[:, 2]
    rate = camera.fy * up_cam[1] + camera.cy * up_cam[2]
    if rate >= 0:  # up points down the image or along the optical axis: the line never reaches row 0
        return np.full(len(points_cam), MAX_HEIGHT_M)
    rise = -(camera.fy * y + camera.cy * z) / rate
    return np.clip(rise, 0.0, MAX_HEIGHT_M)


def _surface_normal(points: np.ndarray) -> np.ndarray | None:
    """The unit normal ``(3,)`` of the plane through ``points`` ``(N, 3)`` (the direction of least
    spread), or None when they are too few or do not lie on a plane."""
    if len(points) < MIN_NEIGHBOURS:
        return None
    spread, axes = np.linalg.eigh(np.cov(points.T))
    return axes[:, 0] if spread[0] < PLANARITY * spread[1] else None


def topmost_upright_returns(
    lidar: KeyframeLidar, camera: CameraModel, up_cam: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Of each group of :data:`COLUMN_PX` image columns, the topmost LiDAR return of ``lidar`` if it
    lies on an upright surface (up is ``up_cam`` ``(3,)`` in the camera frame) at least
    :data:`MIN_DEPTH_M` away: camera-frame points ``(S, 3)`` and the unit horizontal directions
    along their surfaces ``(S, 3)``. The surface is the plane through the returns within
    :data:`NEIGHBOUR_FRACTION` of the point's depth (the keyframe's normal prior leaves out the
    topmost rings, whose neighbourhoods are one-sided)."""
    if not len(lidar.pixels):
        return np.zeros((0, 3)), np.zeros((0, 3))
    rows, cols = np.divmod(lidar.pixels, lidar.shape[1])
    group = cols // COLUMN_PX
    order = np.lexsort((rows, group))
    topmost = order[np.r_[True, np.diff(group[order]) != 0]]
    topmost = topmost[lidar.points[topmost, 2] >= MIN_DEPTH_M]
    tree = cKDTree(lidar.points)
    points, along = [], []
    for index in topmost:
        point = lidar.points[index].astype(np.float64)
        near = tree.query_ball_point(point, NEIGHBOUR_FRACTION * point[2])
        normal = _surface_normal(lidar.points[near].astype(np.float64))
        if normal is None or abs(float(normal @ up_cam)) > UPRIGHT_MAX_COS:
            continue
        direction = np.cross(up_cam, normal)
        points.append(point)
        along.append(direction / np.linalg.norm(direction))
    return np.reshape(points, (-1, 3)), np.reshape(along, (-1, 3))


def _in_sight(raycaster: Any, origin: np.ndarray, points: np.ndarray, margin: float) -> np.ndarray:
    """``(N,)`` bool: world ``points`` ``(N, 3)`` that no face of ``raycaster``'s mesh hides from
    ``origin`` ``(3,)`` by more than ``margin`` (m)."""
    offsets = points - origin
    distance = np.linalg.norm(offsets, axis=1)
    directions = offsets / distance[:, None]
    hit = cast_world_rays(raycaster, np.broadcast_to(origin, points.shape), directions)["t_hit"]
    return hit > distance - margin


def _strip_cells(
    point: np.ndarray, along: np.ndarray, up: np.ndarray, size: float, rise: float
) -> np.ndarray:
    """Square cells ``(C, 4, 3)`` of side ``size`` centred on the upward line through ``point``
    ``(3,)``, horizontal ``along`` ``(3,)``, from one cell below it to ``rise`` above it."""
    bottoms = np.arange(-size, rise, size)
    half = along * size / 2
    base = point + bottoms[:, None] * up
    return np.stack([base - half, base + half, base + half + size * up, base - half + size * up], axis=1)


def confirmed_cells(cells_cam: np.ndarray, sweep: np.ndarray, camera: CameraModel) -> int:
    """How many of a strip's cells, centres ``(C, 3)`` in the camera frame from the bottom up, to
    keep, by the keyframe's swept depth ``sweep`` ``(H, W)`` (NaN: none) in each cell's
    :data:`COLUMN_PX`-wide patch: a cell is confirmed where a depth lies within
    :data:`splat.plane_sweep.AGREE_FRACTION` of its own, contradicted where the patch holds depths and
    all lie beyond it (a building behind shows there). The strip ends one cell above the highest
    confirmed cell, or at the first contradicted cell above it, whichever is lower; a wall too plain
    to match says nothing about where it ends."""
    z = cells_cam[:, 2]
    u, v = np.rint(camera.project(cells_cam)).astype(np.int64).T
    half = COLUMN_PX // 2
    confirmed, contradicted = np.zeros(len(z), dtype=bool), np.zeros(len(z), dtype=bool)
    for index in range(len(z)):
        rows = slice(max(v[index] - half, 0), max(v[index] + half, 0))
        patch = sweep[rows, max(u[index] - half, 0) : max(u[index] + half, 0)]
        patch = patch[np.isfinite(patch)] / z[index] - 1
        confirmed[index] = np.any(np.abs(patch) < AGREE_FRACTION)
        contradicted[index] = len(patch) > 0 and bool(np.all(patch >= AGREE_FRACTION))
    highest = int(np.flatnonzero(confirmed).max()) if confirmed.any() else -1
    end = len(z) if highest < 0 else min(highest + 2, len(z))
    above = np.flatnonzero(contradicted[highest + 1 :])
    return min(end, highest + 1 + int(above[0])) if len(above) else end


def upward_extension(
    camera: CameraModel,
    poses_world_cam: np.ndarray,
    lidars: list[KeyframeLidar],
    up: np.ndarray,
    warm_start: trimesh.Trimesh,
    sweeps: list[np.ndarray | None] | None = None,
) -> UpwardExtension:
    """Strips of cells continuing the upright surfaces at the topmost LiDAR returns of keyframes
    (``camera`` at ``poses_world_cam`` ``(K, 4, 4)`` with their LiDAR returns ``lidars``) straight
    up along world ``up`` ``(3,)`` to the top of each image. One cell of each world grid square (of
    the median cell's side) is kept where keyframes overlap; cells the ``warm_start`` mesh hides
    from the keyframe that made them (a wall continued past a ceiling) and cells the keyframes'
    LiDAR sees through are dropped. With the keyframes' swept depths ``sweeps``
    (:func:`splat.plane_sweep.keyframe_sweeps`), a strip ends one cell above the highest cell its
    keyframe's images confirm (:func:`confirmed_cells`): where a wall ends below the sky or a
    farther building, the cells above no longer match. Returns two triangles a cell."""
    raycaster = mesh_raycaster(warm_start)
    cells, sizes, plane_points, plane_along = [], [], [], []
    for index, (T_world_cam, lidar) in enumerate(zip(poses_world_cam, lidars, strict=True)):
        up_cam = T_world_cam[:3, :3].T @ up
        points, along = topmost_upright_returns(lidar, camera, up_cam)
        if not len(points):
            continue
        rises = rise_to_image_top(points, up_cam, camera)
        world = points @ T_world_cam[:3, :3].T + T_world_cam[:3, 3]
        along_world = along @ T_world_cam[:3, :3].T
        plane_points.append(world)
        plane_along.append(along_world)
        for point, direction, rise, z in zip(world, along_world, rises, points[:, 2], strict=True):
            size = COLUMN_PX * z / camera.fx
            strip = _strip_cells(point, direction, up, size, rise)
            if sweeps is not None and sweeps[index] is not None:
                centres_cam = (strip.mean(axis=1) - T_world_cam[:3, 3]) @ T_world_cam[:3, :3]
                strip = strip[: confirmed_cells(centres_cam, sweeps[index], camera)]
            strip = strip[_in_sight(raycaster, T_world_cam[:3, 3], strip.mean(axis=1), size)]
            cells.append(strip)
            sizes.append(np.full(len(strip), size))
    none = np.zeros((0, 3))
    planes = UprightPlanes(np.concatenate([none, *plane_points]), np.concatenate([none, *plane_along]), up)
    if not cells:
        return UpwardExtension(np.zeros((0, 3, 3)), 0, 0, planes)
    quads, side = np.concatenate(cells), np.concatenate(sizes)
    centres = quads.mean(axis=1)
    kept = one_per_grid_square(centres, float(np.median(side)))
    quads, centres = quads[kept], centres[kept]
    through = seen_through(centres, camera, poses_world_cam, [lidar.depth() for lidar in lidars])
    return UpwardExtension(quad_triangles(quads[~through]), len(planes.points), int(through.sum()), planes)
