"""A square grid on the floor plane, and the floor cells hidden from every camera that the room
still encloses (under and behind furniture).

A warm-start mesh has floor only where the LiDAR or a camera saw it. The floor does not stop
there: it runs on under boxes and tables and behind them up to the walls. Leaving it out costs
recall against any ground truth culled to the camera frusta (which includes hidden surfaces), and a
physics engine's probe falls through where the floor is missing. The completion is conservative:
only cells that the warm-start structure (walls, object footprints, seen floor) closes in on every
side are filled, never across an opening wider than ``2 * closing_m``, never under a wall (tall
structure) and never over a pit (surface well below the plane).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import ndimage
from scipy.spatial import cKDTree

from splat.camera_only import quad_triangles

#: Structure taller than this above the floor is a wall: no floor is completed under it.
WALL_HEIGHT_M = 1.8
#: Samples of high vertical faces a cell needs to count as under a wall.
MIN_WALL_SAMPLES = 3
#: LiDAR returns lower than this above the floor plane are the floor itself.
FLOOR_CLEARANCE_M = 0.1
#: A column of returns this tall stands on the floor (a wall, a box), one shorter may not (a table top).
STANDING_SPAN_M = 0.4
#: Returns within this of the floor plane are ground the LiDAR saw: the floor, a kerb, a pavement.
GROUND_BAND_M = 0.3
#: Returns above this height but within GROUND_BAND_M, in a cell with none higher up to
#: WALL_HEIGHT_M, lie on raised level ground (a street's pavement, a step): the floor does not run
#: on under its slab. Each stands for the cells within RAISED_GROUND_REACH_M of it, the gap between
#: a spinning LiDAR's rings on a pavement beside the car.
RAISED_GROUND_M = 0.05
RAISED_GROUND_REACH_M = 0.45
#: Within this distance of a camera along the floor the ground fill lays fine cells and the floor is
#: near enough for many pixels and the LiDAR's returns to train it; beyond it a street's road lies
#: between a spinning LiDAR's far rings, a few pixels high (a room's floor ends within it).
NEAR_FLOOR_M = 8.0


@dataclass(frozen=True)
class PlaneGrid:
    """Square cells of ``cell_m`` on the plane ``n·x + d = 0`` (``plane`` ``(4,)``, unit ``n``)."""

    plane: np.ndarray
    cell_m: float

    @property
    def basis(self) -> tuple[np.ndarray, np.ndarray]:
        """Two orthonormal in-plane directions ``(3,)`` each."""
        n = self.plane[:3]
        u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        return u, np.cross(n, u)

    def along(self, points: np.ndarray) -> np.ndarray:
        """Coordinates ``(N, 2)`` in metres of points ``(N, 3)`` projected onto the plane (along
        :attr:`basis`)."""
        u, v = self.basis
        return np.column_stack([points @ u, points @ v])

    def cells(self, points: np.ndarray) -> np.ndarray:
        """Integer cell coordinates ``(N, 2)`` of points ``(N, 3)`` projected onto the plane."""
        return np.floor(self.along(points) / self.cell_m).astype(np.int64)

    def near(self, cells: np.ndarray, points: np.ndarray, radius_m: float) -> np.ndarray:
        """``(C,)`` True where the centre of a cell of ``cells`` ``(C, 2)`` lies within ``radius_m``
        of a point of ``points`` ``(N, 3)`` along the plane."""
        if len(cells) == 0 or len(points) == 0:
            return np.zeros(len(cells), dtype=bool)
        distance, _ = cKDTree(self.along(points)).query((cells + 0.5) * self.cell_m)
        return distance <= radius_m

    def heights(self, points: np.ndarray) -> np.ndarray:
        """Signed heights ``(N,)`` of points ``(N, 3)`` above the plane."""
        return points @ self.plane[:3] + self.plane[3]

    def lying_on(self, triangles: np.ndarray, tolerance_m: float = 0.03) -> np.ndarray:
        """``(F,)`` True where all three corners of ``triangles`` ``(F, 3, 3)`` lie within
        ``tolerance_m`` of the plane: floor, as a grid cell or a flat patch of it."""
        return np.all(np.abs(self.heights(triangles.reshape(-1, 3))).reshape(-1, 3) <= tolerance_m, axis=1)

    def upright_squares(self, points: np.ndarray, towards: np.ndarray) -> np.ndarray:
        """Two triangles ``(2P, 3, 3)`` per point ``(P, 3)``: an upright square of ``cell_m`` centred on
        it, facing the horizontal direction to ``towards`` ``(P, 3)`` (a camera)."""
        n = self.plane[:3]
        facing = towards - points
        facing -= np.outer(facing @ n, n)
        facing /= np.maximum(np.linalg.norm(facing, axis=1, keepdims=True), 1e-9)
        across = np.cross(n, facing) * (self.cell_m / 2)
        up = np.broadcast_to(n * (self.cell_m / 2), across.shape)
        corners = np.stack(
            [points - across - up, points + across - up, points + across + up, points - across + up], axis=1
        )
        return quad_triangles(corners)

    def triangles(self, cells: np.ndarray) -> np.ndarray:
        """Two triangles per cell ``(2C, 3, 3)``, wound so that their normals point up."""
        if len(cells) == 0:
            return np.zeros((0, 3, 3))
        u, v = self.basis
        n, d = self.plane[:3], self.plane[3]
        corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float64)
        uv = (cells[:, None, :] + corners[None]) * self.cell_m  # (C, 4, 2)
        xyz = -d * n + uv[..., :1] * u + uv[..., 1:] * v  # (C, 4, 3)
        triangles = quad_triangles(xyz)
        if np.cross(triangles[0, 1] - triangles[0, 0], triangles[0, 2] - triangles[0, 0]) @ n < 0:
            triangles = triangles[:, ::-1]
        return triangles


def range_scaled_cells(
    plane: np.ndarray, cell_m: float, near_m: float, points: np.ndarray, ranges: np.ndarray
) -> np.ndarray:
    """Two triangles per floor cell ``(2C, 3, 3)`` that the floor points ``(N, 3)`` seen from
    ``ranges`` ``(N,)`` metres land in: cells of ``cell_m`` within ``near_m`` and twice as large
    each time the range doubles beyond it (a pixel's footprint on the floor grows faster still;
    cells of one size out to 80 m would be tens of thousands of triangles of a few pixels each)."""
    octave = np.maximum(np.ceil(np.log2(np.maximum(ranges, 1e-9) / near_m)), 0).astype(np.int64)
    parts = [np.zeros((0, 3, 3))]
    for k in np.unique(octave):
        grid = PlaneGrid(plane, cell_m * 2.0**k)
        parts.append(grid.triangles(np.unique(grid.cells(points[octave == k]), axis=0)))
    return np.concatenate(parts)


class ReturnColumns:
    """The LiDAR returns over the floor grid as columns: the lowest and the highest return between
    :data:`FLOOR_CLEARANCE_M` and :data:`WALL_HEIGHT_M` above each cell (not the floor itself, not
    the ceiling). A column whose returns span :data:`STANDING_SPAN_M` or more (a wall, a box's
    side) stands on the floor, though a level LiDAR sees its base only from afar; others (a table
    top) leave the space below them open. A sight line to the floor is blocked where it passes
    through a column, wherever the warm-start mesh has a hole there.

    Args:
        grid: the floor grid.
        points: ``(N, 3)`` LiDAR returns in the world frame.
        tolerance_m: a line passes this close above a column's top or below its bottom.
    """

    def __init__(self, grid: PlaneGrid, points: np.ndarray, tolerance_m: float = 0.05) -> None:
        self.grid, self.tolerance_m = grid, tolerance_m
        heights = grid.heights(points)
        between = (heights > FLOOR_CLEARANCE_M) & (heights < WALL_HEIGHT_M)
        cells, heights = grid.cells(points[between]), heights[between]
        self.low = cells.min(axis=0) if len(cells) else np.zeros(2, dtype=np.int64)
        shape = tuple(cells.max(axis=0) - self.low + 1) if len(cells) else (1, 1)
        index = tuple((cells - self.low).T)
        self.top, self.bottom = np.full(shape, -np.inf), np.full(shape, np.inf)
        np.maximum.at(self.top, index, heights)
        np.minimum.at(self.bottom, index, heights)
        self.bottom[self.top - self.bottom >= STANDING_SPAN_M] = 0.0

    def first_crossing(
        self, origin: np.ndarray, points: np.ndarray, margin_m: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where the straight lines from ``origin`` ``(3,)`` to floor points ``(N, 3)`` first pass
        through a column, before the last ``margin_m`` of their way: ``(N,)`` True where one does,
        and ``(N, 3)`` the point of the line there (meaningless where none does)."""
        if len(points) == 0:
            return np.zeros(0, dtype=bool), np.zeros((0, 3))
        length = np.linalg.norm(points - origin, axis=1)
        steps = int(np.ceil(2 * length.max() / self.grid.cell_m))
        s = (np.arange(steps) + 0.5) / steps  # (S,) fractions of the way, every half cell or less
        samples = (origin + s[:, None, None] * (points - origin)[None]).reshape(-1, 3)  # (S·N, 3)
        line_height = self.grid.heights(samples)
        cells = self.grid.cells(samples) - self.low
        inside = np.all((cells >= 0) & (cells < self.top.shape), axis=1)
        top, bottom = np.full(len(cells), -np.inf), np.full(len(cells), np.inf)
        top[inside] = self.top[tuple(cells[inside].T)]
        bottom[inside] = self.bottom[tuple(cells[inside].T)]
        tol = self.tolerance_m
        through = ((top >= line_height - tol) & (bottom <= line_height + tol)).reshape(steps, -1)
        through &= s[:, None] * length[None] < length[None] - margin_m
        first = np.argmax(through, axis=0)
        crossing = samples.reshape(steps, -1, 3)[first, np.arange(len(points))]
        return through.any(axis=0), crossing


def enclosed_hidden_cells(
    mesh: trimesh.Trimesh,
    grid: PlaneGrid,
    seen_cells: np.ndarray,
    closing_m: float = 0.6,
    max_samples: int = 500_000,
    lidar: np.ndarray | None = None,
) -> np.ndarray:
    """Floor cells ``(H, 2)`` that neither the mesh nor ``seen_cells`` ``(S, 2)`` (floor the cameras
    saw through mesh holes) cover, but that the room closes in on.

    A connected patch of such cells of which half or more hold a LiDAR return (``lidar``
    ``(N, 3)``) within :data:`GROUND_BAND_M` of the plane, or lie within
    :data:`RAISED_GROUND_REACH_M` of a return on raised level ground (:data:`RAISED_GROUND_M`), is
    ground that was seen, not hidden, and is left out: a street's pavement a kerb above the road
    (its returns lie as far apart as the LiDAR's rings, more than a cell), or road the mapper's
    mesh missed between the rings (the LiDAR fill covers that). Patch by patch, so that no strip
    is cut out of the floor under furniture (the returns on a box's sides stand in cells with
    higher ones); the returns do not join the footprint, since far rings would close in on open
    ground.

    The mesh is sampled by area (about nine samples per cell). Up-facing samples within half a
    cell of the plane are floor; from there up to :data:`WALL_HEIGHT_M` they are structure
    (object footprints, wall bases); higher ones on vertical faces mark walls where a cell has
    :data:`MIN_WALL_SAMPLES` of them (a ceiling does not);
    more than two cells below the plane mark a pit. Floor and structure are closed morphologically
    over ``closing_m`` (bridging gaps in the LiDAR mesh), and the holes of that footprint that are
    neither floor, wall nor pit are returned.
    """
    count = int(min(max_samples, max(1.0, mesh.area / (grid.cell_m / 3) ** 2)))
    samples, faces = trimesh.sample.sample_surface(mesh, count, seed=0)
    height = grid.heights(samples)
    facing_up = np.asarray(mesh.face_normals)[faces] @ grid.plane[:3]
    vertical = np.abs(facing_up) < 0.3
    cells = grid.cells(samples)
    floor = (np.abs(height) < grid.cell_m / 2) & (facing_up > 0.7)
    structure = (height >= grid.cell_m / 2) & (height < WALL_HEIGHT_M)
    wall = (height >= WALL_HEIGHT_M) & vertical
    pit = height < -2 * grid.cell_m
    covered = np.concatenate([cells[floor], seen_cells.reshape(-1, 2)])
    footprint = np.concatenate([covered, cells[structure]])
    if len(footprint) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    radius = max(1, int(np.ceil(closing_m / grid.cell_m)))
    low = footprint.min(axis=0) - radius - 1
    shape = tuple(footprint.max(axis=0) - low + radius + 2)

    def raster(c: np.ndarray) -> np.ndarray:
        image = np.zeros(shape, dtype=bool)
        inside = np.all((c >= low) & (c - low < shape), axis=1)
        image[tuple((c[inside] - low).T)] = True
        return image

    closed = ndimage.binary_closing(raster(footprint), structure=_disk(radius))
    enclosed = ndimage.binary_fill_holes(closed)
    # Closing the floor over one cell keeps cells that random sampling happened to miss out.
    floor_cover = ndimage.binary_closing(raster(covered), structure=np.ones((3, 3), dtype=bool))
    # A wall cell needs a few samples (a wall has dozens): one steep face of a noisy TSDF ceiling
    # left a 15 cm hole in the completed floor, where a physics probe fell through.
    walls, count = np.unique(cells[wall], axis=0, return_counts=True)
    hidden = enclosed & ~floor_cover & ~raster(walls[count >= MIN_WALL_SAMPLES]) & ~raster(cells[pit])
    if lidar is not None:
        heights = grid.heights(lidar)
        ground = raster(grid.cells(lidar[np.abs(heights) < GROUND_BAND_M]))
        raised = raster(grid.cells(lidar[(heights > RAISED_GROUND_M) & (heights < GROUND_BAND_M)]))
        raised &= ~raster(grid.cells(lidar[(heights >= GROUND_BAND_M) & (heights < WALL_HEIGHT_M)]))
        reach = int(np.ceil(RAISED_GROUND_REACH_M / grid.cell_m))
        ground |= ndimage.binary_dilation(raised, structure=_disk(reach))
        parts, count = ndimage.label(hidden, structure=np.ones((3, 3), dtype=bool))
        seen_share = ndimage.mean(ground, parts, np.arange(1, count + 1))
        hidden &= np.concatenate([[False], seen_share < 0.5])[parts]
    return np.argwhere(hidden) + low


def _disk(radius: int) -> np.ndarray:
    """``(2r+1, 2r+1)`` bool: the cells within ``radius`` cells of the centre one."""
    return np.hypot(*np.mgrid[-radius : radius + 1, -radius : radius + 1]) <= radius


def on_floor(floor: PlaneGrid | None, triangles: np.ndarray) -> np.ndarray:
    """``(F,)`` bool: which ``triangles`` ``(F, 3, 3)`` lie on the ``floor`` plane (all three corners
    within :data:`FLOOR_CLEARANCE_M`); all False without a floor."""
    if floor is None:
        return np.zeros(len(triangles), dtype=bool)
    return floor.lying_on(triangles, FLOOR_CLEARANCE_M)


def on_far_floor(floor: PlaneGrid | None, triangles: np.ndarray, cameras: np.ndarray) -> np.ndarray:
    """``(F,)`` bool: which ``triangles`` ``(F, 3, 3)`` lie on the ``floor`` plane (:func:`on_floor`)
    farther than :data:`NEAR_FLOOR_M` along it from every camera centre ``(K, 3)``."""
    far = on_floor(floor, triangles)
    if floor is None or not far.any() or not len(cameras):
        return far
    distance, _ = cKDTree(floor.along(cameras)).query(floor.along(triangles[far].mean(axis=1)))
    far[np.flatnonzero(far)[distance <= NEAR_FLOOR_M]] = False
    return far
