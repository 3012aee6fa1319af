import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from rig import InputError, OutOfRangeError, Trajectory, make_transform


def constant_velocity(
    n: int = 6, dt_ns: int = 100_000_000
) -> tuple[Trajectory, np.ndarray, np.ndarray, np.ndarray]:
    """Screw motion: constant linear velocity v and angular velocity w about a fixed axis."""
    v = np.array([0.4, -0.1, 0.05])
    w = np.array([0.1, 0.3, -0.2])  # rad/s
    p0 = np.array([1.0, 2.0, 0.5])
    R0 = Rotation.from_rotvec([0.3, -0.2, 1.0])
    t_ns = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * dt_ns  # epoch-sized stamps
    ts = (t_ns - t_ns[0]) * 1e-9
    rotations = (R0 * Rotation.from_rotvec(ts[:, None] * w)).as_matrix()
    return Trajectory.from_poses(t_ns, make_transform(rotations, p0 + ts[:, None] * v)), p0, v, w


def test_interpolation_is_exact_at_knots() -> None:
    trajectory, *_ = constant_velocity()
    poses = trajectory.interpolate(trajectory.t_ns)
    assert np.array_equal(poses, trajectory.poses)
    assert np.array_equal(trajectory.interpolate(int(trajectory.t_ns[3])), trajectory.poses[3])


def test_constant_velocity_motion_is_reproduced_between_knots() -> None:
    trajectory, p0, v, w = constant_velocity()
    query = np.linspace(trajectory.t_start_ns, trajectory.t_end_ns, 97).astype(np.int64)
    poses = trajectory.interpolate(query)
    ts = (query - trajectory.t_start_ns) * 1e-9
    np.testing.assert_allclose(poses[:, :3, 3], p0 + ts[:, None] * v, atol=1e-12)
    expected = (Rotation.from_rotvec([0.3, -0.2, 1.0]) * Rotation.from_rotvec(ts[:, None] * w)).as_matrix()
    np.testing.assert_allclose(poses[:, :3, :3], expected, atol=1e-12)


def test_query_outside_the_span_raises_unless_clamped() -> None:
    trajectory, *_ = constant_velocity()
    with pytest.raises(OutOfRangeError, match="outside the trajectory"):
        trajectory.interpolate(trajectory.t_end_ns + 1)
    with pytest.raises(OutOfRangeError):
        trajectory.interpolate(np.array([trajectory.t_start_ns, trajectory.t_start_ns - 1]))
    held = trajectory.interpolate(
        np.array([trajectory.t_start_ns - 10**9, trajectory.t_end_ns + 10**9]), clamp=True
    )
    assert np.array_equal(held, trajectory.poses[[0, -1]])


def test_single_pose_trajectory_answers_at_its_stamp() -> None:
    t = Trajectory.from_poses(np.array([5], dtype=np.int64), np.eye(4)[None])
    assert np.array_equal(t.interpolate(5), np.eye(4))
    assert np.array_equal(t.interpolate(np.array([0, 9]), clamp=True), np.stack([np.eye(4)] * 2))


def test_repeated_stamp_uses_the_last_pose_and_blends_around_it() -> None:
    poses = make_transform(
        np.stack([np.eye(3)] * 4), np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0.0]])
    )
    t = Trajectory.from_poses(np.array([0, 10, 10, 20], dtype=np.int64), poses)
    assert t.interpolate(10)[0, 3] == 2.0
    assert t.interpolate(15)[0, 3] == pytest.approx(2.5)
    assert t.interpolate(5)[0, 3] == pytest.approx(0.5)


def test_out_of_order_times_are_rejected() -> None:
    with pytest.raises(InputError, match="out-of-order timestamp at pose 2"):
        Trajectory.from_poses(np.array([0, 10, 5], dtype=np.int64), np.stack([np.eye(4)] * 3))


def test_non_unit_quaternion_is_rejected() -> None:
    with pytest.raises(InputError, match="unit quaternion") as info:
        Trajectory.from_quaternions(
            np.array([0, 1]), np.zeros((2, 3)), [[0, 0, 0, 1], [0, 0, 0, 2]], source="x.txt"
        )
    assert info.value.field == "q" and info.value.path == "x.txt"


@given(
    st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6),
    st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6),
    st.floats(0.0, 1.0),
)
def test_interpolated_pose_is_rigid_and_between_its_knots(
    a: list[float], b: list[float], frac: float
) -> None:
    poses = make_transform(Rotation.from_rotvec([a[:3], b[:3]]).as_matrix(), np.array([a[3:], b[3:]]))
    trajectory = Trajectory.from_poses(np.array([0, 1_000_000], dtype=np.int64), poses)
    pose = trajectory.interpolate(round(frac * 1_000_000))
    R = pose[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    # The rotation travels along the geodesic: its angles to both ends add up to the total.
    angle = lambda R1, R2: Rotation.from_matrix(R1.T @ R2).magnitude()  # noqa: E731
    total = angle(poses[0, :3, :3], poses[1, :3, :3])
    assert angle(poses[0, :3, :3], R) + angle(R, poses[1, :3, :3]) == pytest.approx(total, abs=1e-9)
