import numpy as np

from rig.camera import CameraModel
from splat.camera_only import (
    EXPLAINED_MIN_M,
    SIZE_MAX_FRACTION,
    beyond_lidar_reach,
    camera_only_seeds,
    facing_triangles,
    seen_through,
    unexplained_points,
)

#: Looking along +x from 1.6 m up (camera z = world x, camera y = world -z).
CAMERA = CameraModel("pinhole", 64, 48, [[40, 0, 31.5], [0, 40, 23.5], [0, 0, 1]], [])
POSE = np.array([[0, 0, 1, 0], [-1, 0, 0, 0], [0, -1, 0, 1.6], [0, 0, 0, 1]], dtype=float)


def _depth_of_a_wall(x_m: float, rows: slice = slice(None)) -> np.ndarray:
    """The camera's LiDAR depth image of a wall at ``x_m`` ahead, returns in ``rows`` only."""
    depth = np.zeros((CAMERA.height, CAMERA.width))
    depth[rows] = x_m
    return depth


def _road_and_facade() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LiDAR on a road (z = 0, x in 0..20 m); sparse points on the road and on a facade top at
    x = 25 m, z = 6..10 m, above the LiDAR's reach; one camera at the origin, 1.6 m up (centre)."""
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
    seeds = camera_only_seeds(points, colors, lidar, CAMERA, POSE[None], [np.zeros((48, 64))])
    assert len(seeds.triangles) == 40 and seeds.n_points == 90 and seeds.n_unexplained == 40
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
    assert "40 camera-only triangles" in seeds.reason and "0 of those the LiDAR sees through" in seeds.reason


def test_no_seeds_where_the_lidar_explains_everything():
    lidar, points, _ = _road_and_facade()
    seeds = camera_only_seeds(
        points[:50], np.zeros((50, 3), np.uint8), lidar, CAMERA, POSE[None], [_depth_of_a_wall(30.0)]
    )
    assert seeds.triangles.shape == (0, 3, 3) and seeds.colors.shape == (0, 3, 3)


def test_points_the_lidar_sees_through_are_wrong_and_above_its_field_are_kept():
    """A wall 20 m ahead, its returns in the image's lower half: a point 10 m ahead in front of
    the returns is seen through by both keyframes; one above the returns, or behind the wall, is
    not; one keyframe's vote is not enough."""
    ahead = np.array([[10.0, 0.0, 1.0], [10.0, 0.0, 4.0], [25.0, 0.0, 1.0]])  # rows 26, 11, 25
    lower_half = _depth_of_a_wall(20.0, slice(24, None))
    poses = np.stack([POSE, POSE])
    assert seen_through(ahead, CAMERA, poses, [lower_half, lower_half]).tolist() == [True, False, False]
    assert not seen_through(ahead, CAMERA, poses, [lower_half, np.zeros_like(lower_half)]).any()
    seeds = camera_only_seeds(ahead[:2], np.zeros((2, 3), np.uint8), np.zeros((0, 3)), CAMERA, poses,
                              [lower_half, lower_half])  # fmt: skip
    np.testing.assert_allclose(seeds.triangles.mean(axis=1), ahead[1:2], atol=1e-9)


def test_only_points_above_the_lidars_reach_are_seeded():
    """Returns (5 m ahead) in rows 20 and below: a point 10 m ahead at row 26 is within the LiDAR's
    reach in its column (the LiDAR simply missed it), one at row 11 is above it."""
    points = np.array([[10.0, 0.0, 1.0], [10.0, 0.0, 4.0]])  # rows 26, 11
    depth = _depth_of_a_wall(5.0, slice(20, None))
    assert beyond_lidar_reach(points, CAMERA, POSE[None], [depth]).tolist() == [False, True]
    assert beyond_lidar_reach(points, CAMERA, POSE[None], [np.zeros_like(depth)]).all()  # no return
    seeds = camera_only_seeds(
        points, np.zeros((2, 3), np.uint8), np.zeros((0, 3)), CAMERA, POSE[None], [depth]
    )
    np.testing.assert_allclose(seeds.triangles.mean(axis=1), points[1:], atol=1e-9)
    assert seeds.n_unexplained == 1
