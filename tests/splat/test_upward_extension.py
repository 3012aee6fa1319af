import numpy as np
import trimesh

from rig.camera import CameraModel
from slam_bridge.scene import KeyframeLidar
from splat.upward_extension import (
    COLUMN_PX,
    MAX_HEIGHT_M,
    rise_to_image_top,
    topmost_upright_returns,
    upward_extension,
)

#: Looking along world +x from 1.6 m up (camera z = world x, camera y = world -z).
CAMERA = CameraModel("pinhole", 64, 48, [[40, 0, 31.5], [0, 40, 23.5], [0, 0, 1]], [])
POSE = np.array([[0, 0, 1, 0], [-1, 0, 0, 0], [0, -1, 0, 1.6], [0, 0, 0, 1]], dtype=float)
UP = np.array([0.0, 0.0, 1.0])
NO_MESH = trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))


def _wall_returns(x_m: float, rows: range) -> KeyframeLidar:
    """Returns on a wall ``x_m`` ahead at every pixel of ``rows``."""
    cols, rws = np.meshgrid(np.arange(CAMERA.width), np.array(rows))
    pixels = np.column_stack([cols.ravel(), rws.ravel()]).astype(np.float64)
    points = CAMERA.unproject(pixels, x_m).astype(np.float32)
    flat = rws.ravel() * CAMERA.width + cols.ravel()
    order = np.argsort(flat)
    return KeyframeLidar(flat[order], points[order], (CAMERA.height, CAMERA.width))


def _road_returns() -> KeyframeLidar:
    """Returns on the road (world z = 0) wherever the camera sees it."""
    cols, rows = np.meshgrid(np.arange(CAMERA.width), np.arange(30, CAMERA.height))
    pixels = np.column_stack([cols.ravel(), rows.ravel()]).astype(np.float64)
    rays = CAMERA.unproject(pixels)
    points = (rays * (1.6 / rays[:, 1:2])).astype(np.float32)  # camera y = 1.6 m down to the road
    return KeyframeLidar(rows.ravel() * CAMERA.width + cols.ravel(), points, (CAMERA.height, CAMERA.width))


def test_a_wall_cut_by_the_lidar_is_continued_in_its_plane_to_the_image_top():
    lidar = _wall_returns(10.0, range(30, 48))
    points, along = topmost_upright_returns(lidar, CAMERA, POSE[:3, :3].T @ UP)
    assert len(points) >= CAMERA.width // COLUMN_PX  # a strip per column group (the last is narrow)
    np.testing.assert_allclose(np.abs(along @ np.array([1.0, 0.0, 0.0])), 1.0, atol=1e-6)  # along the wall

    extension = upward_extension(CAMERA, POSE[None], [lidar], UP, NO_MESH)
    corners = extension.triangles.reshape(-1, 3)
    np.testing.assert_allclose(corners[:, 0], 10.0, atol=1e-6)  # in the wall's plane
    top_of_image = 1.6 + 10.0 * 23.5 / 40.0  # where row 0 meets the wall
    assert top_of_image <= corners[:, 2].max() < top_of_image + 10.0 * COLUMN_PX / 40.0
    lowest_return = 1.6 - 10.0 * (30 - 23.5) / 40.0
    assert corners[:, 2].min() < lowest_return  # the strips overlap the LiDAR's part of the wall

    # The wall's plane goes with it, for the plane sweep's cells (one per strip).
    assert len(extension.planes.points) == extension.n_strips >= CAMERA.width // COLUMN_PX
    np.testing.assert_allclose(extension.planes.points[:, 0], 10.0, atol=1e-5)
    np.testing.assert_allclose(np.abs(extension.planes.normals[:, 0]), 1.0, atol=1e-6)


def test_the_road_is_not_continued_upwards():
    lidar = _road_returns()
    assert len(topmost_upright_returns(lidar, CAMERA, POSE[:3, :3].T @ UP)[0]) == 0
    assert len(upward_extension(CAMERA, POSE[None], [lidar], UP, NO_MESH).triangles) == 0


def test_cells_the_lidar_sees_through_are_left_out():
    low_wall = _wall_returns(10.0, range(30, 48))
    behind = _wall_returns(30.0, range(0, 10))  # a taller building 20 m behind, above the low wall
    extension = upward_extension(CAMERA, np.stack([POSE] * 3), [low_wall, behind, behind], UP, NO_MESH)
    assert extension.n_seen_through > 0
    corners = extension.triangles.reshape(-1, 3)
    on_low_wall = corners[np.abs(corners[:, 0] - 10.0) < 1e-6]
    seen_through_from = 1.6 + 10.0 * (23.5 - 10) / 40.0  # the row-10 line on the low wall
    assert on_low_wall[:, 2].max() < seen_through_from + 10.0 * COLUMN_PX / 40.0


def test_strips_stop_at_the_height_limit_where_the_upward_line_never_leaves_the_image():
    point = np.array([[0.0, 0.0, 10.0]])
    looking_up = np.array([0.0, 0.0, 1.0])  # up along the optical axis: the line runs to the centre
    assert rise_to_image_top(point, looking_up, CAMERA)[0] == MAX_HEIGHT_M
    level = np.array([0.0, -1.0, 0.0])
    np.testing.assert_allclose(rise_to_image_top(point, level, CAMERA), [10.0 * 23.5 / 40.0])


def test_a_wall_is_not_continued_past_the_ceiling_that_hides_it():
    lidar = _wall_returns(10.0, range(30, 48))
    ceiling = trimesh.Trimesh([[0, -20, 3], [12, -20, 3], [12, 20, 3], [0, 20, 3]], [[0, 1, 2], [0, 2, 3]])
    corners = upward_extension(CAMERA, POSE[None], [lidar], UP, ceiling).triangles.reshape(-1, 3)
    assert len(corners) and corners[:, 2].max() < 3.0 + 10.0 * COLUMN_PX / 40.0


def test_a_strip_ends_a_cell_above_what_the_images_confirm_and_runs_on_where_they_say_nothing():
    lidar = _wall_returns(10.0, range(30, 48))
    matched = np.full((CAMERA.height, CAMERA.width), np.nan, dtype=np.float32)
    matched[28:30] = 10.0  # the images match the wall just above the LiDAR; sky above
    cut = upward_extension(CAMERA, POSE[None], [lidar], UP, NO_MESH, [matched]).triangles.reshape(-1, 3)
    top_of_image = 1.6 + 10.0 * 23.5 / 40.0
    highest_match = 1.6 + 10.0 * (23.5 - 28) / 40.0
    assert len(cut) and highest_match < cut[:, 2].max() <= highest_match + 2 * 10.0 * COLUMN_PX / 40.0
    assert cut[:, 2].max() < top_of_image

    farther = np.where(np.isfinite(matched), 30.0, np.nan).astype(np.float32)  # a building behind
    behind = upward_extension(CAMERA, POSE[None], [lidar], UP, NO_MESH, [farther]).triangles.reshape(-1, 3)
    assert len(behind) and behind[:, 2].max() < highest_match  # only the cell below the LiDAR's top

    plain = np.full_like(matched, np.nan)  # a wall too plain to match
    unswept = upward_extension(CAMERA, POSE[None], [lidar], UP, NO_MESH, [None]).triangles
    runs_on = upward_extension(CAMERA, POSE[None], [lidar], UP, NO_MESH, [plain]).triangles
    assert np.array_equal(runs_on, unswept) and runs_on.reshape(-1, 3)[:, 2].max() >= top_of_image
