"""An extrinsic over moving frames is no better than the time offset that placed them."""

from __future__ import annotations

import numpy as np
import pytest

from calib.session_calib import RETIME_REACH_S, motion_guess, offset_error, timing_reasons
from calib.time_offset import MAX_OFFSET_S, TimeOffsetResult
from rig.trajectory import Trajectory


def _estimate(offset_s: float, std_s: float, verdict: str = "ok") -> TimeOffsetResult:
    return TimeOffsetResult(offset_s, std_s, verdict, [], 0.9, 0.3, 500)


def _straight(speed_m_s: float) -> Trajectory:
    """10 s along x at a constant speed, a pose every 0.1 s."""
    t_ns = np.arange(101, dtype=np.int64) * 100_000_000
    poses = np.tile(np.eye(4), (101, 1, 1))
    poses[:, 0, 3] = speed_m_s * t_ns * 1e-9
    return Trajectory.from_poses(t_ns, poses)


def test_the_offset_may_be_off_by_its_distance_from_the_estimate_and_its_interval():
    assert offset_error(_estimate(0.015, 0.002), 0.015) == pytest.approx(1.96 * 0.002)
    # An estimate from the jackknife's 20 blocks reaches Student's t: 2.09 standard deviations.
    blocks = TimeOffsetResult(0.015, 0.002, "ok", [], 0.9, 0.3, 500, interval_95=2.093)
    assert offset_error(blocks, 0.015) == pytest.approx(2.093 * 0.002)
    # Not applied (poorly constrained): the step used 0 s while the motion said 15 ± 8.7 ms.
    assert offset_error(_estimate(0.015, 0.0087, "poorly constrained"), 0.0) == pytest.approx(
        0.0320, abs=1e-4
    )
    no_estimate = _estimate(np.nan, np.inf, "poorly constrained")
    assert offset_error(no_estimate, 0.0) == MAX_OFFSET_S


def test_frames_that_move_too_far_within_the_doubt_are_named():
    frame_t = np.array([2.0, 5.0, 8.0])
    turning = (np.linspace(0, 10, 11), np.full(11, np.radians(30.0)))  # 30 °/s at every frame
    # 30 °/s × 2 ms = 0.06° and 1 m/s × 2 ms = 0.2 cm: within the extrinsic's limits.
    assert timing_reasons(frame_t, _straight(1.0), turning, 0.0, 0.002) == []
    (reason,) = timing_reasons(frame_t, _straight(1.0), turning, 0.0, 0.02)
    assert "may be 20 ms off" in reason and "turning 30°/s" in reason and "0.60°" in reason
    # A car at 2 m/s that does not turn: 2 m/s × 20 ms = 4 cm, over the 2.5 cm limit.
    still = (np.linspace(0, 10, 11), np.zeros(11))
    (reason,) = timing_reasons(frame_t, _straight(2.0), still, 0.0, 0.02)
    assert "moving 2.00 m/s" in reason and "4.0 cm" in reason
    assert timing_reasons(frame_t, _straight(2.0), None, 0.0, 0.01) == []  # 2 cm


def test_the_motions_rotation_is_a_guess_where_the_extrinsic_search_can_pin_the_offset():
    """The rates fit (their rotation is in the result) but the offset's spread is over its limit:
    the rotation is still a rough extrinsic, as long as the search's window covers the doubt."""
    turn = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])

    def estimate(std_s: float, verdict: str, fitted: bool = True) -> TimeOffsetResult:
        extra = {"R_cam_lidar_from_motion": turn.tolist()} if fitted else {}
        return TimeOffsetResult(0.015, std_s, verdict, [], 0.9, 0.3, 500, extra, interval_95=2.093)

    np.testing.assert_array_equal(motion_guess(estimate(0.002, "ok"))[:3, :3], turn)
    np.testing.assert_array_equal(motion_guess(estimate(0.0052, "poorly constrained"))[:3, :3], turn)
    assert RETIME_REACH_S < 2.093 * 0.03 and motion_guess(estimate(0.03, "poorly constrained")) is None
    assert motion_guess(estimate(0.002, "poorly constrained", fitted=False)) is None  # weak correlation
