"""Camera-only cells moved onto the upright surfaces the LiDAR touched: onto the plane, along their
pixel rays, only when the plane is near in depth, near where it was measured and not grazed."""

from __future__ import annotations

import numpy as np

from splat.upright_planes import SNAP_ALONG_M, UprightPlanes, snap_to_planes

UP = np.array([0.0, 0.0, 1.0])
ORIGIN = np.array([0.0, 0.0, 1.6])


def _wall(x_m: float, y_m: float = 0.0) -> UprightPlanes:
    """A facade in the plane x = ``x_m``, measured at (x_m, y_m, 2 m): it runs along world y."""
    return UprightPlanes(np.array([[x_m, y_m, 2.0]]), np.array([[0.0, 1.0, 0.0]]), UP)


def _cell(centre: np.ndarray, side: float = 0.5) -> np.ndarray:
    """A square ``(1, 4, 3)`` around ``centre`` facing the origin (in a plane x = const)."""
    h = side / 2
    return (centre + np.array([[0, -h, -h], [0, h, -h], [0, h, h], [0, -h, h]]))[None]


def test_a_cell_near_a_facade_moves_onto_it_along_its_pixel_rays() -> None:
    cell = _cell(np.array([29.0, 1.0, 8.0]))  # stereo put it 1 m short of the facade at 30 m
    moved, snapped = snap_to_planes(cell, ORIGIN[None], _wall(30.0), tolerance=0.05)

    assert snapped.tolist() == [True]
    np.testing.assert_allclose(moved[0, :, 0], 30.0)
    rays, moved_rays = cell[0] - ORIGIN, moved[0] - ORIGIN
    np.testing.assert_allclose(np.cross(rays, moved_rays), 0.0, atol=1e-9)  # the same pixels
    assert np.all(np.einsum("ck,ck->c", rays, moved_rays) > 0)


def test_of_two_facades_the_nearer_in_depth_wins() -> None:
    planes = UprightPlanes(
        np.array([[31.0, 0.0, 2.0], [29.5, 0.0, 2.0]]), np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]), UP
    )
    moved, _ = snap_to_planes(_cell(np.array([29.0, 0.0, 6.0])), ORIGIN[None], planes, tolerance=0.05)
    np.testing.assert_allclose(moved[0, :, 0], 29.5)


def test_cells_stay_where_no_facade_qualifies() -> None:
    cells = np.concatenate(
        [
            _cell(np.array([25.0, 0.0, 8.0])),  # 17 % short of the facade: a different surface
            _cell(np.array([29.0, SNAP_ALONG_M + 2.0, 8.0])),  # beyond where the facade was measured
        ]
    )
    moved, snapped = snap_to_planes(cells, np.stack([ORIGIN, ORIGIN]), _wall(30.0), tolerance=0.05)
    assert not snapped.any()
    np.testing.assert_array_equal(moved, cells)

    # A ray that grazes the facade (it runs nearly along the ray) would stretch the cell.
    centre = np.array([20.0, 1.5, 2.0])
    grazing = UprightPlanes(centre[None], np.array([[0.999, 0.045, 0.0]]), UP)  # through the cell
    cell = _cell(centre)
    assert not snap_to_planes(cell, ORIGIN[None], grazing, tolerance=0.05)[1].any()


def test_no_planes_or_no_cells_change_nothing() -> None:
    cell = _cell(np.array([29.0, 0.0, 8.0]))
    none = UprightPlanes(np.zeros((0, 3)), np.zeros((0, 3)), UP)
    moved, snapped = snap_to_planes(cell, ORIGIN[None], none, tolerance=0.05)
    np.testing.assert_array_equal(moved, cell)
    assert not snapped.any()
    moved, snapped = snap_to_planes(np.zeros((0, 4, 3)), np.zeros((0, 3)), _wall(30.0), tolerance=0.05)
    assert moved.shape == (0, 4, 3) and snapped.shape == (0,)
