from pathlib import Path

import numpy as np
import pytest

from rig.session import SessionReader
from rig.sweep_registration import RegistrationLog, SweepSettings, extended_at_both_ends, registered_sweeps
from rig.trajectory import Trajectory


def test_the_second_registration_follows_the_truth_closer_than_the_first(quick_room: Path) -> None:
    """The quick room's 30 sweeps, registered again de-skewed: the poses lie nearer the truth (ATE
    after alignment), and each sweep comes with its points' times."""
    from eval.trajectory_metrics import absolute_trajectory_error
    from rig.trajectory_io import read_tum

    scans = list(SessionReader(quick_room / "session.mcap").scans("/lidar/points"))
    log = RegistrationLog()
    sweeps = list(registered_sweeps(scans, SweepSettings(), log))
    assert len(sweeps) == len(log.poses) == 30
    truth = read_tum(quick_room / "ground_truth" / "trajectory_lidar.tum")
    t_ns = np.array(log.t_ns, dtype=np.int64)
    first = absolute_trajectory_error(Trajectory.from_poses(t_ns, np.stack(log.poses)), truth).rmse_m
    second = absolute_trajectory_error(
        Trajectory.from_poses(t_ns, np.stack([s.pose for s in sweeps])), truth
    ).rmse_m
    assert second < first
    for sweep, scan in zip(sweeps, scans, strict=True):
        assert len(sweep.points) == len(sweep.point_t_ns) == len(sweep.dynamic)
        assert (
            int(scan.t_host) <= sweep.point_t_ns.min()
            and sweep.point_t_ns.max() < int(scan.t_host) + 200_000_000
        )


def test_without_the_see_through_test_each_sweep_is_registered_once(quick_room: Path) -> None:
    scans = list(SessionReader(quick_room / "session.mcap").scans("/lidar/points"))[:5]
    log = RegistrationLog()
    sweeps = list(registered_sweeps(scans, SweepSettings(dynamic=None), log))
    assert log.static_odometry is None and not any(s.dynamic.any() for s in sweeps)
    for sweep, pose in zip(sweeps, log.poses, strict=True):
        np.testing.assert_array_equal(sweep.pose, pose)


def test_first_and_last_sweeps_are_de_skewed_with_the_motion_repeated() -> None:
    """A LiDAR moving 0.3 m and turning 2° per 0.1 s: beyond the end poses the trajectory goes on
    at that rate instead of standing still (a sweep reaches past the poses around it)."""
    from scipy.spatial.transform import Rotation

    from rig.transforms import make_transform

    turn = Rotation.from_euler("z", 2, degrees=True).as_matrix()
    poses = np.stack([make_transform(np.eye(3), [0, 0, 0]), make_transform(turn, [0.3, 0, 0])])
    trajectory = extended_at_both_ends(np.array([0, 100_000_000]), poses)
    before, after = trajectory.interpolate(np.array([-50_000_000, 150_000_000]))
    np.testing.assert_allclose(before[:3, 3], [-0.15, 0, 0], atol=0.01)
    np.testing.assert_allclose(after[:3, 3], [0.45, 0, 0], atol=0.01)
    assert np.degrees(Rotation.from_matrix(after[:3, :3]).as_euler("xyz")[2]) == pytest.approx(3.0, abs=1e-6)
