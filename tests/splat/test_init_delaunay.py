"""splat.init_delaunay: unique tetrahedron faces as triangles, their colours, subsampling, bad input."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial import Delaunay

from rig.errors import InputError
from splat.init_delaunay import delaunay_triangles

CUBE = np.array(list(itertools.product([0.0, 1.0], repeat=3)))
CUBE_AND_CENTRE = np.vstack([CUBE, [[0.5, 0.5, 0.5]]])


def corner_sets(triangles: np.ndarray, points: np.ndarray) -> list[frozenset[int]]:
    """Each triangle ``(F, 3, 3)`` as the set of indices of its corners in ``points`` ``(N, 3)``."""
    index = {tuple(p): i for i, p in enumerate(points)}
    return [frozenset(index[tuple(v)] for v in tri) for tri in triangles]


def test_cube_faces_are_the_unique_tetrahedron_faces() -> None:
    triangles, _ = delaunay_triangles(CUBE_AND_CENTRE, np.zeros((9, 3)))
    expected = {
        frozenset(face)
        for tet in Delaunay(CUBE_AND_CENTRE).simplices
        for face in itertools.combinations(tet.tolist(), 3)
    }
    got = corner_sets(triangles, CUBE_AND_CENTRE)
    assert triangles.shape == (30, 3, 3)  # 12 tetrahedra: 12 hull faces + 36 / 2 inner faces
    assert len(set(got)) == len(got)
    assert set(got) == expected
    assert triangles.dtype == np.float64


def test_colours_follow_the_points() -> None:
    rng = np.random.default_rng(1)
    points = rng.normal(size=(50, 3))
    colors = rng.integers(0, 256, size=(50, 3), dtype=np.uint8)
    triangles, tri_colors = delaunay_triangles(points, colors)
    lookup = {tuple(p): c / 255.0 for p, c in zip(points, colors, strict=True)}
    expected = np.array([[lookup[tuple(v)] for v in tri] for tri in triangles])
    np.testing.assert_array_equal(tri_colors, expected)
    assert tri_colors.shape == triangles.shape and tri_colors.dtype == np.float64


def test_duplicate_points_are_merged() -> None:
    points = np.vstack([CUBE_AND_CENTRE, CUBE_AND_CENTRE[:4]])
    colors = np.vstack([np.full((9, 3), 0.25), np.full((4, 3), 0.75)])
    triangles, tri_colors = delaunay_triangles(points, colors)
    assert len(triangles) == 30
    assert (tri_colors == 0.25).all()  # the first occurrence's colour


def test_subsampling_is_seeded() -> None:
    rng = np.random.default_rng(2)
    points = rng.uniform(size=(200, 3))
    colors = rng.uniform(size=(200, 3))
    a, _ = delaunay_triangles(points, colors, max_points=40, seed=7)
    b, _ = delaunay_triangles(points, colors, max_points=40, seed=7)
    c, _ = delaunay_triangles(points, colors, max_points=40, seed=8)
    np.testing.assert_array_equal(a, b)
    assert len(np.unique(a.reshape(-1, 3), axis=0)) == 40
    assert not np.array_equal(np.unique(a.reshape(-1, 3), axis=0), np.unique(c.reshape(-1, 3), axis=0))


def test_max_edge_drops_long_triangles() -> None:
    triangles, colors = delaunay_triangles(CUBE_AND_CENTRE, np.zeros((9, 3)), max_edge_m=1.0)
    edges = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2)
    assert (edges <= 1.0).all()
    # Only the 12 inner triangles of a centre-to-corner pair and a cube edge (√0.75, √0.75, 1) remain.
    assert len(triangles) == 12 and len(colors) == 12


@pytest.mark.parametrize(
    ("points", "message"),
    [
        (CUBE[:3], "at least 4 distinct points"),
        (np.vstack([CUBE[:3], CUBE[:3]]), "at least 4 distinct points"),
        (CUBE[[0, 2, 4, 6]], "coplanar"),  # the x = 0 face
        (np.outer(np.arange(6.0), [1.0, 2.0, 3.0]), "coplanar"),
    ],
)
def test_degenerate_input_is_an_input_error(points: np.ndarray, message: str) -> None:
    with pytest.raises(InputError, match=message):
        delaunay_triangles(points, np.zeros_like(points))


@pytest.mark.parametrize(
    ("points", "colors", "field"),
    [
        (np.zeros((9, 2)), np.zeros((9, 2)), "points"),
        (CUBE_AND_CENTRE, np.zeros((8, 3)), "colors"),
        (CUBE_AND_CENTRE, np.full((9, 3), 2.0), "colors"),
        (np.vstack([CUBE, [[np.nan, 0.0, 0.0]]]), np.zeros((9, 3)), "points"),
    ],
)
def test_malformed_arrays_name_the_field(points: np.ndarray, colors: np.ndarray, field: str) -> None:
    with pytest.raises(InputError) as err:
        delaunay_triangles(points, colors)
    assert err.value.field == field
