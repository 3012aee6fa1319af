import numpy as np
import trimesh

from splat.lidar_fill import (
    EXPLAINED_MIN_M,
    MIN_KEYFRAMES,
    VOXEL_M,
    lidar_fill,
    unexplained_returns,
    voxel_levels,
)

CAMERAS = np.array([[0.0, 0.0, 1.6]])


def _road_mesh() -> trimesh.Trimesh:
    """A 20 x 8 m road at z = 0 in front of the camera."""
    return trimesh.Trimesh([[0, -4, 0], [20, -4, 0], [20, 4, 0], [0, 4, 0]], [[0, 1, 2], [0, 2, 3]])


def _returns() -> tuple[np.ndarray, np.ndarray]:
    """Returns on the road (x 0..20 m) and on a wall at x = 10 m, y 5..9 m, z 0..3 m beside it."""
    rng = np.random.default_rng(0)
    road = np.column_stack([rng.uniform(0, 20, 4000), rng.uniform(-4, 4, 4000), rng.normal(0, 0.01, 4000)])
    wall = np.column_stack([np.full(3000, 10.0), rng.uniform(5, 9, 3000), rng.uniform(0, 3, 3000)])
    return road, wall


def test_returns_on_the_mesh_are_explained_and_the_others_are_not():
    road, wall = _returns()
    unexplained = unexplained_returns(_road_mesh(), np.concatenate([road, wall]), CAMERAS)
    assert not unexplained[: len(road)].any()
    assert unexplained[len(road) :].all()
    near = np.array([[5.0, 0.0, 0.5 * EXPLAINED_MIN_M]])
    assert not unexplained_returns(_road_mesh(), near, CAMERAS).any()


def _held_by(points: np.ndarray, n_keyframes: int) -> list[np.ndarray]:
    """``points`` split between ``n_keyframes`` keyframes, every one holding each part of the scene."""
    return [points[k::n_keyframes] for k in range(n_keyframes)]


def test_the_wall_the_mesh_misses_is_filled_in_its_plane():
    road, wall = _returns()
    fill = lidar_fill(_road_mesh(), _held_by(np.concatenate([road, wall]), MIN_KEYFRAMES), CAMERAS)
    assert fill.n_unexplained == len(wall) and fill.n_returns == len(road) + len(wall)
    corners = fill.triangles.reshape(-1, 3)
    np.testing.assert_allclose(corners[:, 0], 10.0, atol=0.02)  # in the wall's plane
    centroids = fill.triangles.mean(axis=1)
    assert (centroids[:, 1] > 5 - VOXEL_M).all() and (centroids[:, 2] > -VOXEL_M).all()
    # about one triangle per voxel of the 4 x 3 m wall, together covering it
    assert 0.5 * 12 / VOXEL_M**2 < len(fill.triangles) < 2 * 12 / VOXEL_M**2
    areas = np.linalg.norm(np.cross(fill.triangles[:, 1] - fill.triangles[:, 0],
                                    fill.triangles[:, 2] - fill.triangles[:, 0]), axis=1) / 2  # fmt: skip
    assert areas.sum() > 12.0


def test_nothing_is_added_where_the_mesh_explains_every_return():
    road, _ = _returns()
    fill = lidar_fill(_road_mesh(), _held_by(road, MIN_KEYFRAMES), CAMERAS)
    assert len(fill.triangles) == 0 and fill.n_unexplained == 0


def test_returns_too_few_keyframes_hold_are_not_filled():
    """A car moving with the robot lies somewhere else in every sweep: each keyframe alone holds it."""
    road, wall = _returns()
    car = [wall[k::5] + np.array([1.5 * k, 0.0, 0.0]) for k in range(5)]  # 1.5 m further in each keyframe
    keyframes = [np.concatenate([road[k::5], part]) for k, part in enumerate(car)]
    fill = lidar_fill(_road_mesh(), keyframes, CAMERAS)
    assert fill.n_unexplained == len(wall) and fill.n_voxels > 0
    assert len(fill.triangles) == 0


def test_far_returns_fill_voxels_as_large_as_their_spread():
    """A far wall's returns land in different small voxels in each sweep; grown with the range, the
    voxels gather them from enough keyframes, and the triangles grow with them."""
    rng = np.random.default_rng(1)
    far = 60.0  # a voxel of VOXEL_M * 2 here: VOXEL_FRACTION * 60 m = 0.6 m
    assert voxel_levels(np.array([[far, 0.0, 1.6], [5.0, 0.0, 1.6]]), CAMERAS).tolist() == [1, 0]
    # Each keyframe holds one return per 0.5 m voxel of a 6 x 4 m wall, at its own place within it.
    y, z = np.meshgrid(np.arange(-3, 3, 0.5) + 0.25, np.arange(0, 4, 0.5) + 0.25)
    keyframes = [
        np.column_stack([np.full(y.size, far), y.ravel(), z.ravel()])
        + np.column_stack([np.zeros(y.size), rng.uniform(-0.2, 0.2, (y.size, 2))])
        for _ in range(MIN_KEYFRAMES)
    ]
    fill = lidar_fill(_road_mesh(), keyframes, CAMERAS)
    assert 0.5 * 24 / (2 * VOXEL_M) ** 2 <= len(fill.triangles) <= 24 / (2 * VOXEL_M) ** 2
    np.testing.assert_allclose(fill.triangles.reshape(-1, 3)[:, 0], far, atol=0.05)  # in the wall's plane
    radius = np.linalg.norm(fill.triangles[:, 0] - fill.triangles.mean(axis=1), axis=1)
    assert radius.min() >= 2 * VOXEL_M - 1e-9
