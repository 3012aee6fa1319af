import numpy as np

from splat.camera_only import (
    EXPLAINED_MIN_M,
    SIZE_MAX_FRACTION,
    camera_only_seeds,
    facing_triangles,
    unexplained_points,
)


def _road_and_facade() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LiDAR on a road (z = 0, x in 0..20 m); sparse points on the road and on a facade top at
    x = 25 m, z = 6..10 m, above the LiDAR's reach; one camera at the origin, 1.6 m up."""
    rng = np.random.default_rng(0)
    road = np.column_stack([rng.uniform(0, 20, 5000), rng.uniform(-4, 4, 5000), np.zeros(5000)])
    on_road = road[:50] + rng.normal(0, 0.02, (50, 3))
    facade = np.column_stack([np.full(40, 25.0), rng.uniform(-4, 4, 40), rng.uniform(6, 10, 40)])
    return road, np.concatenate([on_road, facade]), np.array([[0.0, 0.0, 1.6]])


def test_points_the_lidar_explains_are_not_seeded():
    lidar, points, cameras = _road_and_facade()
    unexplained = unexplained_points(points, lidar, cameras)
    assert not unexplained[:50].any()
    assert unexplained[50:].all()


def test_the_explained_radius_grows_with_depth():
    lidar = np.array([[0.0, 0.0, 0.0]])
    cameras = np.array([[0.0, 0.0, 1.0], [100.0, 0.0, 1.0]])
    near_camera = np.array([[0.0, 0.0, 1.5 * EXPLAINED_MIN_M]])  # 0.5 m from the first camera
    assert unexplained_points(near_camera, lidar, cameras).all()
    far = np.array([[0.0, 0.0, 1.5 * EXPLAINED_MIN_M]])
    assert not unexplained_points(far, lidar, np.array([[0.0, 50.0, 0.0]])).any()  # 50 m away: 1.5 m


def test_facing_triangles_are_centred_equilateral_and_face_their_normal():
    points = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    triangles = facing_triangles(points, normals, np.array([0.5, 2.0]))
    np.testing.assert_allclose(triangles.mean(axis=1), points, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(triangles - points[:, None], axis=2), [[0.5] * 3, [2.0] * 3])
    face_normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    face_normals /= np.linalg.norm(face_normals, axis=1, keepdims=True)
    np.testing.assert_allclose(np.abs(np.sum(face_normals * normals, axis=1)), 1.0, atol=1e-12)


def test_seeds_sit_on_the_unexplained_points_facing_the_camera_sized_by_their_neighbours():
    lidar, points, cameras = _road_and_facade()
    colors = np.tile(np.array([[200, 100, 50]], dtype=np.uint8), (len(points), 1))
    seeds = camera_only_seeds(points, colors, lidar, cameras)
    assert len(seeds.triangles) == 40 and seeds.n_points == 90
    np.testing.assert_allclose(seeds.triangles.mean(axis=1), points[50:], atol=1e-9)
    np.testing.assert_allclose(seeds.colors, np.broadcast_to(colors[50:, None] / 255.0, (40, 3, 3)))
    centres = seeds.triangles.mean(axis=1)
    towards = cameras[0] - centres
    towards /= np.linalg.norm(towards, axis=1, keepdims=True)
    normals = np.cross(
        seeds.triangles[:, 1] - seeds.triangles[:, 0], seeds.triangles[:, 2] - seeds.triangles[:, 0]
    )
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(np.abs(np.sum(normals * towards, axis=1)), 1.0, atol=1e-9)
    radii = np.linalg.norm(seeds.triangles[:, 0] - centres, axis=1)
    depth = np.linalg.norm(centres - cameras[0], axis=1)
    assert np.all(radii <= SIZE_MAX_FRACTION * depth + 1e-9)
    assert 0.3 < np.median(radii) < 2.0  # 40 points on 8 × 4 m: about 1 m apart
    assert "40 camera-only triangles" in seeds.reason


def test_no_seeds_where_the_lidar_explains_everything():
    lidar, points, cameras = _road_and_facade()
    seeds = camera_only_seeds(points[:50], np.zeros((50, 3), np.uint8), lidar, cameras)
    assert seeds.triangles.shape == (0, 3, 3) and seeds.colors.shape == (0, 3, 3)
