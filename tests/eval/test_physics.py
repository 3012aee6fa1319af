import numpy as np
import pytest
import trimesh

from eval.physics import compare_drops, drop_probes, footprint_grid

pytest.importorskip("pybullet")


def floor_with_step(hole: bool = False, step_height: float = 0.0) -> trimesh.Trimesh:
    """A 4 m × 2 m floor (z = 0) as a grid of 10 cm squares; optionally a 30 cm hole in the middle
    and a raised second half (a step)."""
    xs, ys = np.meshgrid(np.arange(0, 4.0, 0.1), np.arange(-1.0, 1.0, 0.1))
    squares = np.stack([xs.ravel(), ys.ravel()], axis=1)
    if hole:
        centre = squares + 0.05
        squares = squares[~((np.abs(centre[:, 0] - 2.0) < 0.15) & (np.abs(centre[:, 1]) < 0.15))]
    vertices, faces = [], []
    for x, y in squares:
        z = step_height if x >= 2.0 else 0.0
        base = len(vertices)
        vertices += [[x, y, z], [x + 0.1, y, z], [x + 0.1, y + 0.1, z], [x, y + 0.1, z]]
        faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return trimesh.Trimesh(np.array(vertices), np.array(faces), process=False)


PATH = np.array([[0.5, 0.0, 0.5], [3.5, 0.0, 0.5]])


def test_footprint_grid_spans_the_path() -> None:
    starts = footprint_grid(PATH, up=[0, 0, 1], spacing_m=0.5, half_width_m=0.5, clearance_m=0.2)
    assert len(starts) == 7 * 3
    np.testing.assert_allclose(starts[:, 2], 0.3)
    assert set(np.round(starts[:, 1], 6)) == {-0.5, 0.0, 0.5}


def test_mesh_against_itself_gives_zero_error() -> None:
    gt = floor_with_step(step_height=0.15)
    starts = footprint_grid(PATH, up=[0, 0, 1])
    a, b = drop_probes(gt, starts), drop_probes(gt, starts)
    result = compare_drops(a, b)
    assert result.fall_through_rate == 0.0 and result.max_height_error_m == 0.0
    low = starts[:, 0] < 1.9
    assert np.allclose(a.rest_height[low], 0.04, atol=0.005)  # sphere radius above the floor


def test_hole_in_the_floor_gives_fall_throughs() -> None:
    starts = np.array([[2.0, 0.0, 0.3], [1.0, 0.0, 0.3], [3.0, 0.5, 0.3]])
    result = compare_drops(
        drop_probes(floor_with_step(hole=True), starts), drop_probes(floor_with_step(), starts)
    )
    assert result.probes == 3
    assert result.fall_through_rate == pytest.approx(1 / 3)


def test_wrong_step_height_is_measured() -> None:
    starts = footprint_grid(PATH, up=[0, 0, 1])
    result = compare_drops(
        drop_probes(floor_with_step(step_height=0.10), starts),
        drop_probes(floor_with_step(step_height=0.15), starts),
    )
    assert result.fall_through_rate == 0.0
    assert result.max_height_error_m == pytest.approx(0.05, abs=0.005)
