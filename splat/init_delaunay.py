"""The TS+ baseline initialisation: every face of a point cloud's 3D Delaunay tetrahedralisation.

TS+ starts from the COLMAP points (``SCENE_DIR/sparse_points.ply``); the LiDAR-Delaunay ablation
starts from LiDAR points, far more of them, hence the seeded subsample.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, QhullError

from rig.errors import InputError

#: The four triangular faces of a tetrahedron, as indices into its four corners.
TET_FACES = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])


def delaunay_triangles(
    points: np.ndarray,
    colors: np.ndarray,
    *,
    max_points: int | None = None,
    max_edge_m: float | None = None,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of the Delaunay tetrahedralisation of ``points``, each face once.

    Duplicate points are dropped first (the first one's colour is kept), then at most
    ``max_points`` are drawn at random (seeded by ``seed``).

    Args:
        points: ``(N, 3)`` positions in metres.
        colors: ``(N, 3)`` RGB, float in [0, 1] or uint8.
        max_points: subsample to this many points; None keeps all.
        max_edge_m: drop triangles with an edge longer than this; None keeps all (as TS+ does).
        seed: seed of the subsample.

    Returns:
        triangles ``(F, 3, 3)`` float64 and their per-vertex colours ``(F, 3, 3)`` float64 in [0, 1].

    Raises:
        InputError: malformed arrays, fewer than 4 distinct points, or all of them coplanar.
    """
    points, colors = _checked(points, colors)
    points, first = np.unique(points, axis=0, return_index=True)
    colors = colors[first]
    if max_points is not None:
        if max_points < 1:
            raise InputError(f"expected a positive point count, got {max_points}", field="max_points")
        if len(points) > max_points:
            pick = np.sort(np.random.default_rng(seed).choice(len(points), max_points, replace=False))
            points, colors = points[pick], colors[pick]
    if len(points) < 4:
        raise InputError(f"a tetrahedralisation needs at least 4 distinct points, got {len(points)}")
    try:
        simplices = Delaunay(points).simplices
    except QhullError:
        raise InputError(
            f"cannot tetrahedralise {len(points)} points: they are coplanar (or collinear)"
        ) from None
    faces = np.unique(np.sort(simplices[:, TET_FACES].reshape(-1, 3), axis=1), axis=0)
    triangles = points[faces]
    if max_edge_m is not None:
        edges = triangles - np.roll(triangles, 1, axis=1)
        short = (np.linalg.norm(edges, axis=2) <= max_edge_m).all(axis=1)
        faces, triangles = faces[short], triangles[short]
    return triangles, colors[faces]


def _checked(points: np.ndarray, colors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(N, 3)`` as float64 and colours ``(N, 3)`` as float64 in [0, 1], validated."""
    points = np.asarray(points)
    colors = np.asarray(colors)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"expected shape (N, 3), got {points.shape}", field="points")
    if colors.shape != points.shape:
        raise InputError(f"expected shape {points.shape}, got {colors.shape}", field="colors")
    points = points.astype(np.float64)
    if not np.isfinite(points).all():
        raise InputError("holds NaN or Inf", field="points")
    if colors.dtype == np.uint8:
        return points, colors / 255.0
    colors = colors.astype(np.float64)
    if not ((colors >= 0.0) & (colors <= 1.0)).all():
        raise InputError("expected values in [0, 1] (or uint8)", field="colors")
    return points, colors
