"""The two repairs of a warm-start mesh: snapping its vertices onto the LiDAR returns, and
completing the floor no camera sees where the room encloses it."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from training_scene import WALL_Y, corner_mesh, write_training_scene

from slam_bridge.scene import KeyframeLidar, load_scene
from splat.floor_cells import PlaneGrid, enclosed_hidden_cells
from splat.lidar_snap import snap_to_lidar

FLOOR = np.array([0.0, 0.0, 1.0, 0.0])


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return load_scene(write_training_scene(tmp_path_factory.mktemp("scene")))


def _plane_distance(vertices: np.ndarray, on_wall: np.ndarray) -> np.ndarray:
    """Distance ``(V,)`` of each corner vertex (floor z = 0, wall y = 3) to its own plane."""
    return np.where(on_wall, np.abs(vertices[:, 1] - WALL_Y), np.abs(vertices[:, 2]))


def _observed(scene, vertices: np.ndarray) -> np.ndarray:
    """``(V,)`` True where some training view has the vertex in its image, in front of it."""
    seen = np.zeros(len(vertices), dtype=bool)
    for keyframe in scene.split("train"):
        T = keyframe.T_world_cam
        cam = (vertices - T[:3, 3]) @ T[:3, :3]
        front = cam[:, 2] > 0.1
        pixels = scene.camera.project(np.where(front[:, None], cam, 1.0))
        seen |= front & scene.camera.in_image(pixels)
    return seen


def test_snapping_moves_noisy_vertices_back_onto_the_surface(scene):
    mesh = corner_mesh(8)
    clean = np.asarray(mesh.vertices, dtype=np.float64)
    rng = np.random.default_rng(0)
    noisy = clean + rng.normal(0.0, 0.05, clean.shape)
    snap = snap_to_lidar(noisy, scene, scene.split("train"))
    on_wall = (clean[:, 1] > WALL_Y - 1e-6) & (clean[:, 2] > 1e-6)
    observed = _observed(scene, noisy) & (_plane_distance(noisy, on_wall) < snap.radius_m)
    before = _plane_distance(noisy, on_wall)[observed]
    after = _plane_distance(snap.vertices, on_wall)[observed]
    assert snap.n_snapped >= 0.8 * observed.sum()
    assert 0.03 < snap.radius_m <= 0.5  # adapted to the noise: about 3 × 5 cm
    assert np.median(after) < 0.1 * np.median(before)
    assert np.median(after) < 0.005
    untouched = ~_observed(scene, noisy)
    np.testing.assert_array_equal(snap.vertices[untouched], noisy[untouched])


def test_snapping_a_clean_mesh_barely_moves_it(scene):
    clean = np.asarray(corner_mesh(8).vertices, dtype=np.float64)
    snap = snap_to_lidar(clean, scene, scene.split("train"))
    assert snap.n_snapped > 0
    assert snap.radius_m < 0.1  # residuals come from the pixel grid only
    assert np.abs(snap.vertices - clean).max() < 0.01


def test_snapping_without_lidar_returns_leaves_the_mesh_alone(scene, monkeypatch):
    empty = KeyframeLidar(np.zeros(0, np.int64), np.zeros((0, 3), np.float32), (48, 64))
    monkeypatch.setattr(type(scene), "lidar", lambda self, keyframe: empty)
    vertices = np.asarray(corner_mesh(4).vertices, dtype=np.float64)
    snap = snap_to_lidar(vertices, scene, scene.split("train"))
    assert snap.n_snapped == 0
    np.testing.assert_array_equal(snap.vertices, vertices)


def _box(size, centre) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=size, transform=trimesh.transformations.translation_matrix(centre))


def _room_with_box(pit: bool = False) -> trimesh.Trimesh:
    """A 4 × 4 × 2.5 m room (a 10 cm floor grid, ceiling, four walls) with a 1 × 1 × 0.6 m box at
    (2, 2); the floor under the box is missing (no sensor sees it), and with ``pit`` the box is
    replaced by the bottom of a 0.5 m deep pit."""
    room = _box((4, 4, 2.5), (2, 2, 1.25))
    room.invert()
    room = trimesh.Trimesh(room.vertices, room.faces[room.triangles_center[:, 2] > 1e-6])  # floor goes
    corners = np.array([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], dtype=float)
    floor = trimesh.Trimesh(*trimesh.remesh.subdivide_to_size(corners, np.array([[0, 1, 2], [0, 2, 3]]), 0.1))
    under_box = np.all(np.abs(floor.triangles_center[:, :2] - 2) < 0.5, axis=1)
    floor = trimesh.Trimesh(floor.vertices, floor.faces[~under_box])
    if pit:
        inside = _box((0.8, 0.8, 0.01), (2, 2, -0.5))
    else:  # a SLAM mesh has no face under the box
        box = _box((1, 1, 0.6), (2, 2, 0.3))
        inside = trimesh.Trimesh(box.vertices, box.faces[box.face_normals[:, 2] > -0.5])
    return trimesh.util.concatenate([room, floor, inside])


def _centres(grid: PlaneGrid, cells: np.ndarray) -> np.ndarray:
    """World centres ``(C, 3)`` of grid cells ``(C, 2)``: midpoints of a diagonal of each."""
    return grid.triangles(cells)[: len(cells), [0, 2]].mean(axis=1)


def test_the_floor_under_a_box_is_completed_and_nothing_beyond_the_walls():
    grid = PlaneGrid(FLOOR, 0.1)
    cells = enclosed_hidden_cells(_room_with_box(), grid, np.zeros((0, 2), dtype=np.int64))
    centres = _centres(grid, cells)[:, :2]
    assert len(cells) > 0
    assert np.all((centres > 0) & (centres < 4))  # inside the room
    under_box = np.all(np.abs(centres - 2) < 0.5, axis=1)
    assert under_box.sum() >= 0.8 * 100  # most of the 1 m² (100 cells) under the box
    assert (~under_box).sum() <= 0.2 * under_box.sum()  # little else: the floor is there already


def test_no_completion_over_a_pit_or_without_enclosure():
    grid = PlaneGrid(FLOOR, 0.1)
    pit = enclosed_hidden_cells(_room_with_box(pit=True), grid, np.zeros((0, 2), dtype=np.int64))
    centres = _centres(grid, pit)[:, :2]
    assert not np.all(np.abs(centres - 2) < 0.35, axis=1).any()
    open_floor = trimesh.Trimesh(
        np.array([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], float), np.array([[0, 1, 2], [0, 2, 3]])
    )
    assert len(enclosed_hidden_cells(open_floor, grid, np.zeros((0, 2), dtype=np.int64))) == 0


def test_plane_grid_triangles_cover_their_cells_facing_up():
    grid = PlaneGrid(FLOOR, 0.2)
    cells = np.array([[0, 0], [3, -2]])
    triangles = grid.triangles(cells)
    assert triangles.shape == (4, 3, 3)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    assert np.all(normals[:, 2] > 0)
    np.testing.assert_allclose(0.5 * np.linalg.norm(normals, axis=1).sum(), 2 * 0.04)
    np.testing.assert_array_equal(np.unique(grid.cells(triangles.mean(axis=1)), axis=0), cells)
