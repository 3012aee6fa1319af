"""The repairs of a warm-start mesh: snapping its vertices onto the LiDAR returns, completing the
floor no camera sees where the room encloses it, and the floor too far for the mesh to bridge."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from training_scene import CAMERA, WALL_Y, camera_poses, corner_mesh, write_training_scene

from rig.plane_fit import ransac_plane
from slam_bridge.scene import KeyframeLidar, load_scene
from splat.floor_cells import PlaneGrid, ReturnColumns, enclosed_hidden_cells, on_floor
from splat.init_mesh import fit_floor_plane, ground_fill
from splat.lidar_points import lidar_points
from splat.lidar_snap import snap_to_lidar
from splat.trainer import scene_floor

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


def test_a_wall_the_simplification_broke_still_encloses_the_hidden_floor():
    """The quick demo's warm start, simplified to 15 000 faces, lost a thin stretch of one wall in
    one recording of three, and the hidden floor behind the cameras (1 100 cells) went with it:
    half the physics probes fell through. The room's walls enclose it in the mesh as it was."""
    room = _box((4, 4, 2.5), (2, 2, 1.25))
    room.invert()
    room = trimesh.Trimesh(*trimesh.remesh.subdivide_to_size(room.vertices, room.faces, 0.2))
    room = trimesh.Trimesh(room.vertices, room.faces[room.triangles_center[:, 2] > 1e-6])
    corners = np.array([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], dtype=float)
    floor = trimesh.Trimesh(*trimesh.remesh.subdivide_to_size(corners, np.array([[0, 1, 2], [0, 2, 3]]), 0.1))
    c = floor.triangles_center
    hole = (np.abs(c[:, 0] - 2) < 0.8) & (c[:, 1] > 2.5)  # 1.6 x 1.5 m to the far wall, behind the cameras
    whole = trimesh.util.concatenate([room, trimesh.Trimesh(floor.vertices, floor.faces[~hole])])
    centres = whole.triangles_center
    broken = (np.abs(centres[:, 1] - 4) < 1e-6) & (np.abs(centres[:, 0] - 2) < 1.0)  # 2 m of the far wall
    simplified = trimesh.Trimesh(whole.vertices, whole.faces[~broken])
    poses = camera_poses(6)
    poses[:, :3, :3] = np.diag([-1.0, -1.0, 1.0]) @ poses[:, :3, :3]  # looking along -y, away from it
    poses[:, :3, 3] += (2.0, 1.0, 0.0)
    assert len(ground_fill(simplified, CAMERA, poses, cell_m=0.1).hidden) <= 0.2 * 480  # corners
    hidden = ground_fill(simplified, CAMERA, poses, cell_m=0.1, enclosing=whole).hidden.mean(axis=1)
    assert len(hidden) >= 0.8 * 480  # two triangles a cell, 240 cells
    assert np.all((np.abs(hidden[:, 0] - 2) < 0.9) & (hidden[:, 1] > 2.4) & (hidden[:, 1] < 4))


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


def _camera_poses(positions: list[tuple[float, float, float]]) -> np.ndarray:
    """Level cameras ``(K, 4, 4)`` at ``positions`` looking along +x (OpenCV axes: y down)."""
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    poses = np.tile(np.eye(4), (len(positions), 1, 1))
    poses[:, :3, :3] = R
    poses[:, :3, 3] = positions
    return poses


def test_the_floor_plane_comes_from_the_returns_not_from_a_tilted_patch_of_mesh():
    """A warm start whose only floor is a small patch tilted by 3° (a simplified TSDF floor seen
    far ahead) and LiDAR returns on the whole floor and on a wall, with the ring a level LiDAR's
    lowest beam draws on the wall at 0.25 m (more returns than the floor's): the plane is the
    returns' level floor."""
    rng = np.random.default_rng(0)
    slab = _box((1.0, 1.0, 0.01), (0, 0, 0))
    patch = trimesh.Trimesh(*trimesh.remesh.subdivide_to_size(slab.vertices, slab.faces, 0.1))
    patch.apply_transform(trimesh.transformations.rotation_matrix(np.radians(3.0), (0, 1, 0)))
    patch.apply_translation((4.0, 0.0, 0.2))
    floor = np.column_stack([rng.uniform(-4, 8, (4000, 2)), rng.normal(0.0, 0.01, 4000)])
    wall = np.column_stack([np.full(2000, 8.0), rng.uniform(-4, 4, 2000), rng.uniform(0, 2.5, 2000)])
    ring = np.column_stack([np.full(6000, 8.0), rng.uniform(-4, 4, 6000), rng.normal(0.25, 0.005, 6000)])
    poses = _camera_poses([(0.0, 0.0, 0.45), (1.0, 0.0, 0.45)])
    plane = fit_floor_plane(patch, poses, np.vstack([floor, wall, ring]))
    np.testing.assert_allclose(plane[:3], (0, 0, 1), atol=2e-3)
    assert abs(plane[3]) < 0.005
    tilted = fit_floor_plane(patch, poses)  # without returns: the patch is all there is
    assert tilted is not None and np.degrees(np.arccos(tilted[2])) > 2.0


def test_ransac_keeps_to_hypotheses_near_the_axis():
    rng = np.random.default_rng(1)
    wall = np.column_stack([rng.uniform(0, 4, 3000), np.zeros(3000), rng.uniform(0, 2.5, 3000)])
    floor = np.column_stack([rng.uniform(0, 4, (500, 2)), np.zeros(500)])
    points = np.vstack([wall, floor])
    assert abs(ransac_plane(points, 0.02)[0][1]) > 0.99  # the wall has the most support
    plane, inliers = ransac_plane(points, 0.02, normal_near=(np.array([0.0, 0.0, 1.0]), 10.0))
    assert abs(plane[2]) > 0.99 and len(inliers) >= 500


def test_returns_of_a_wall_block_the_sight_of_the_floor_behind_it():
    """A wall at x = 3 that the warm-start mesh lost: floor points beyond it are hidden, floor
    points before it and the floor's and ceiling's own returns block nothing."""
    rng = np.random.default_rng(2)
    wall = np.column_stack([np.full(3000, 3.0), rng.uniform(-2, 2, 3000), rng.uniform(0.0, 2.6, 3000)])
    floor = np.column_stack([rng.uniform(0, 6, (3000, 2)) - (0, 3), rng.normal(0, 0.01, 3000)])
    ceiling = np.column_stack([rng.uniform(0, 6, (3000, 2)) - (0, 3), np.full(3000, 2.6)])
    columns = ReturnColumns(PlaneGrid(FLOOR, 0.15), np.vstack([wall, floor, ceiling]))
    origin = np.array([0.0, 0.0, 0.45])
    targets = np.array([[1.0, 0.0, 0.0], [2.5, 0.5, 0.0], [3.5, 0.0, 0.0], [5.0, -1.0, 0.0]])
    crossed, at = columns.first_crossing(origin, targets, 0.15)
    np.testing.assert_array_equal(crossed, [False, False, True, True])
    # Where the sight line meets the wall: at x = 3 (within a cell), at the line's height there.
    np.testing.assert_allclose(at[2], [3.0, 0.0, 0.45 * (1 - 3.0 / 3.5)], atol=0.15)
    squares = PlaneGrid(FLOOR, 0.15).upright_squares(at[2:3], origin[None])
    normal = np.cross(squares[0, 1] - squares[0, 0], squares[0, 2] - squares[0, 0])
    assert squares.shape == (2, 3, 3) and abs(normal[2]) < 1e-9 and abs(normal[0]) > 0  # upright, facing x
    open_room = ReturnColumns(PlaneGrid(FLOOR, 0.15), np.vstack([floor, ceiling]))
    assert not open_room.first_crossing(origin, targets, 0.15)[0].any()
    # A table top at 0.74 m over x = 1.5-2.5: the camera at 0.45 m sees the floor under and past it.
    table = np.column_stack([rng.uniform(1.5, 2.5, 2000), rng.uniform(-1, 1, 2000), np.full(2000, 0.74)])
    under_table = ReturnColumns(PlaneGrid(FLOOR, 0.15), np.vstack([table, floor, ceiling]))
    assert not under_table.first_crossing(origin, targets[:2], 0.15)[0].any()
    # Seen from 1.4 m (hand-held), the sight line to the floor at x = 4 m crosses the table top.
    high = np.array([0.0, 0.0, 1.4])
    beyond = np.array([[4.0, 0.0, 0.0]])
    np.testing.assert_array_equal(under_table.first_crossing(high, beyond, 0.15)[0], [True])


def test_one_steep_face_of_a_noisy_ceiling_is_not_a_wall():
    """A single 5 cm vertical face at 2.4 m over the box (a TSDF ceiling's noise) leaves the floor
    under it completed; a real wall there (a 1 × 0.9 m panel) does not."""
    grid = PlaneGrid(FLOOR, 0.1)
    sliver = trimesh.Trimesh([[2.03, 2.05, 2.40], [2.08, 2.05, 2.40], [2.03, 2.05, 2.45]], [[0, 1, 2]])
    below = grid.cells(np.array([[2.05, 2.05, 0.0]]))

    def completed(extra: trimesh.Trimesh) -> bool:
        mesh = trimesh.util.concatenate([_room_with_box(), extra])
        cells = enclosed_hidden_cells(mesh, grid, np.zeros((0, 2), dtype=np.int64))
        return bool((cells == below).all(axis=1).any())

    assert completed(sliver)
    assert not completed(_box((1.0, 0.02, 0.9), (2.0, 2.05, 2.0)))


def test_ground_the_lidar_saw_is_not_completed_as_hidden_floor():
    """A pavement along one wall (y > 3.2 m, 15 cm above the floor) that the mesh lacks but the
    LiDAR hit: without the returns the strip would be completed at the floor's height; with them
    it is left out, and the floor under the box (a few returns of which lie there too) is not."""
    grid = PlaneGrid(FLOOR, 0.1)
    room = _room_with_box()
    strip = (room.triangles_center[:, 1] > 3.2) & (np.abs(room.triangles_center[:, 2]) < 0.01)
    mesh = trimesh.Trimesh(room.vertices, room.faces[~strip])
    none = np.zeros((0, 2), dtype=np.int64)

    def strip_and_box(cells: np.ndarray) -> tuple[int, int]:
        centres = _centres(grid, cells)[:, :2]
        return int((centres[:, 1] > 3.2).sum()), int(np.all(np.abs(centres - 2) < 0.5, axis=1).sum())

    pavement = np.column_stack([*np.mgrid[0.05:4:0.1, 3.25:4:0.1].reshape(2, -1), np.full(8 * 40, 0.15)])
    glimpses = np.array([[1.6, 1.6, 0.0], [2.3, 1.7, 0.0], [1.8, 2.4, 0.0]])  # returns under the box
    without = strip_and_box(enclosed_hidden_cells(mesh, grid, none))
    with_returns = strip_and_box(
        enclosed_hidden_cells(mesh, grid, none, lidar=np.vstack([pavement, glimpses]))
    )
    assert without[0] >= 0.8 * 320 and without[1] >= 80
    assert with_returns == (0, without[1])
    # A spinning LiDAR's rings on the pavement: a return every 40 cm across it, fewer than one per
    # cell, still mark it as seen; returns on the box's sides (cells with higher ones) do not.
    rings = np.column_stack([*np.mgrid[0.05:4:0.1, 3.25:4:0.4].reshape(2, -1), np.full(40 * 2, 0.15)])
    sides = np.array([[x, 1.52, h] for x in np.arange(1.55, 2.5, 0.1) for h in (0.1, 0.2, 0.4, 0.55)])
    sparse = strip_and_box(enclosed_hidden_cells(mesh, grid, none, lidar=np.vstack([rings, sides])))
    assert sparse == (0, without[1])


def test_plane_grid_finds_the_cells_near_points_along_the_plane():
    grid = PlaneGrid(FLOOR, 0.5)
    cells = grid.cells(np.array([[0.1, 0.1, 0.0], [5.1, 0.1, 0.0], [0.1, -3.4, 0.0]]))
    near = grid.near(cells, np.array([[0.0, 0.0, 1.4], [5.0, 0.0, 30.0]]), 1.0)  # heights do not count
    np.testing.assert_array_equal(near, [True, True, False])
    assert grid.near(cells[:0], np.zeros((1, 3)), 1.0).shape == (0,)


def test_floor_a_mapper_put_a_few_centimetres_off_the_plane_stays_floor(scene):
    """The collision mesh keeps the floor no camera sees (:func:`splat.floor_cells.on_floor` of
    :func:`splat.trainer.scene_floor`):
    a street's TSDF road lies 2-4 cm below the plane fitted to the returns, and is still floor; a
    step 25 cm up and a triangle across the wall are not."""
    flat = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 0.3, 0.0]])
    triangles = np.stack(
        [
            flat + np.array([0.0, 0.0, -0.04]),
            flat + np.array([0.0, 0.0, 0.02]),
            flat + np.array([0.0, 0.0, 0.25]),
            [[0, 3, 0], [0.3, 3, 0], [0, 3, 0.5]],
        ]
    )
    train = scene.split("train")
    floor = on_floor(scene_floor(scene, train, lidar_points(scene, train)), triangles)
    np.testing.assert_array_equal(floor, [True, True, False, False])


def test_the_floor_beyond_the_near_range_is_filled_with_coarser_cells_as_far_as_the_lidar_reached():
    """A street's road: the warm start has it near the cameras only, the LiDAR's returns on it
    reach 30 m; the fill covers the rest out to there, its cells growing with the range."""
    poses = camera_poses(3, pitch_deg=5.0)
    near_floor = trimesh.creation.box(extents=(6.0, 6.0, 0.02))
    near_floor.apply_translation((0.0, 2.0, -0.01))
    rng = np.random.default_rng(0)
    lidar = np.column_stack([rng.uniform(-5, 5, 40_000), rng.uniform(0.5, 30.0, 40_000), np.zeros(40_000)])
    fill = ground_fill(near_floor, CAMERA, poses, lidar, cell_m=0.1, max_range_m=4.0, pixel_stride=1)
    assert "coarser ones beyond 4 m" in fill.reason
    centres = fill.triangles.mean(axis=1)
    edges = np.linalg.norm(fill.triangles[:, 1] - fill.triangles[:, 0], axis=1)  # a side or a diagonal
    assert np.abs(fill.triangles[..., 2]).max() < 1e-9
    assert not ((np.abs(centres[:, 0]) < 2.9) & (centres[:, 1] < 4.9)).any()  # none over the mesh
    reach = _range_from_cameras(centres, poses)
    assert (reach > 17.0).sum() > 20 and reach.max() < 30.0 + 1.0
    # Cells of 0.1 m (sides, diagonals) within 4 m; of 0.8 m or more beyond 16 m (plus a cell).
    assert edges[reach < 3.9].max() <= 0.1 * np.sqrt(2) + 1e-6
    assert edges[reach > 17.0].min() >= 0.8 - 1e-6
    near_only = ground_fill(
        near_floor, CAMERA, poses, lidar[np.linalg.norm(lidar, axis=1) < 3.0], cell_m=0.1, max_range_m=4.0
    )
    assert _range_from_cameras(near_only.triangles.mean(axis=1), poses).max() < 4.0 + 0.1


def _range_from_cameras(points: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Distance ``(N,)`` of points ``(N, 3)`` to the nearest camera of ``poses`` ``(K, 4, 4)``."""
    return np.linalg.norm(points[:, None] - poses[None, :, :3, 3], axis=2).min(axis=1)
