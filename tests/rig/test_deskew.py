import numpy as np

from rig.deskew import DESKEW_STEP_NS, deskewed_points
from rig.trajectory import Trajectory
from rig.transforms import make_transform


def _turning(t_ns: np.ndarray, rate_rad_s: float, speed_m_s: float) -> np.ndarray:
    """Poses ``(N, 4, 4)`` of a sensor turning about z and moving along x at times ``(N,)``."""
    angle = rate_rad_s * t_ns * 1e-9
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((len(t_ns), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1
    return make_transform(R, np.column_stack([speed_m_s * t_ns * 1e-9, np.zeros((len(t_ns), 2))]))


def test_each_point_moves_with_the_pose_at_its_step() -> None:
    stamps = np.arange(0, 200_000_001, 10_000_000, dtype=np.int64)
    trajectory = Trajectory.from_poses(stamps, _turning(stamps, 0.5, 1.0))
    rng = np.random.default_rng(0)
    points = rng.uniform(-5, 5, (500, 3))
    times = rng.integers(0, 100_000_000, 500)
    moved = deskewed_points(points, times, trajectory)
    at_step = trajectory.interpolate(times // DESKEW_STEP_NS * DESKEW_STEP_NS)
    expected = np.einsum("nij,nj->ni", at_step[:, :3, :3], points) + at_step[:, :3, 3]
    np.testing.assert_allclose(moved, expected, atol=1e-12)
    exact = deskewed_points(points, times, trajectory, step_ns=1)
    # 0.1 ms of 1 m/s and 0.5 rad/s at up to 8.7 m: at most 0.1 mm + 0.44 mm.
    assert np.linalg.norm(moved - exact, axis=1).max() < 0.6e-3


def test_times_outside_the_trajectory_hold_its_end_poses() -> None:
    stamps = np.array([0, 100_000_000], dtype=np.int64)
    trajectory = Trajectory.from_poses(stamps, _turning(stamps, 1.0, 0.0))
    points = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    moved = deskewed_points(points, np.array([-50_000_000, 150_000_000]), trajectory)
    np.testing.assert_allclose(moved[0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(moved[1], [np.cos(0.1), np.sin(0.1), 0], atol=1e-12)
