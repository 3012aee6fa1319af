"""Time offset from angular-speed signals: recovery, and refusal on weak or uniform motion."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib.intervals import jackknife_interval_95
from calib.time_offset import JACKKNIFE_BLOCKS, estimate_time_offset


def _turning(t: np.ndarray, rng_seed: int = 0) -> np.ndarray:
    """A smooth angular velocity profile ``(N, 3)`` (rad/s): mostly yaw, with turns of varying rate."""
    rng = np.random.default_rng(rng_seed)
    freqs, phases = rng.uniform(0.05, 0.6, (3, 6)), rng.uniform(0, 2 * np.pi, (3, 6))
    waves = np.sin(2 * np.pi * freqs[:, :, None] * t + phases[:, :, None]).sum(axis=1) / 3
    return (np.array([[0.05], [0.05], [0.3]]) * waves + np.array([[0.0], [0.0], [0.3]])).T


#: Rotation from the LiDAR/IMU frame to the camera frame (the virtual rig's axes, roughly).
R_CAM_LIDAR = Rotation.from_euler("xyz", [-90, 0, -90], degrees=True).as_matrix()


def _signals(offset: float, profile, noise_cam: float = 0.02, noise_imu: float = 0.01):
    """Camera samples at 30 Hz (camera frame) and LiDAR-clock gyro at 200 Hz (LiDAR frame) of one
    motion; the LiDAR clock reads ``offset`` less than the camera clock."""
    rng = np.random.default_rng(1)
    t_true_cam = np.arange(0.0, 20.0, 1 / 30)
    t_true_imu = np.arange(0.0, 20.0, 1 / 200)
    w_cam = profile(t_true_cam) @ R_CAM_LIDAR.T + rng.normal(0, noise_cam, (len(t_true_cam), 3))
    w_imu = profile(t_true_imu) + rng.normal(0, noise_imu, (len(t_true_imu), 3))
    return t_true_cam + 100.0, w_cam, t_true_imu + 100.0 - offset, w_imu


@pytest.mark.parametrize("offset", [0.015, -0.12, 0.3])
def test_recovers_offset_within_2_ms(offset: float) -> None:
    result = estimate_time_offset(*_signals(offset, _turning))
    assert result.verdict == "ok", result.reasons
    assert abs(result.time_offset_s - offset) < 0.002
    assert result.std_s < 0.005
    # The spread of 20 blocks has 19 degrees of freedom: Student's t, 2.09 standard deviations.
    assert result.interval_95 == pytest.approx(jackknife_interval_95(JACKKNIFE_BLOCKS))
    assert result.to_json()["interval_95_s"] == pytest.approx(2.093 * result.std_s, rel=1e-3)
    assert result.correlation > 0.9
    R = np.array(result.extra["R_cam_lidar_from_motion"])
    assert Rotation.from_matrix(R @ R_CAM_LIDAR.T).magnitude() < np.radians(1.0)


def test_straight_drive_is_refused() -> None:
    result = estimate_time_offset(*_signals(0.02, lambda t: np.zeros((len(t), 3))))
    assert result.verdict == "poorly constrained"
    assert "too weak" in result.reasons[0]
    assert np.isnan(result.time_offset_s)


def test_uniform_turn_is_refused() -> None:
    result = estimate_time_offset(*_signals(0.02, lambda t: np.tile([0.0, 0.0, 0.5], (len(t), 1))))
    assert result.verdict == "poorly constrained"


def test_too_few_samples_is_refused() -> None:
    t_cam, w_cam, t_imu, w_imu = _signals(0.0, _turning)
    result = estimate_time_offset(t_cam[:5], w_cam[:5], t_imu, w_imu)
    assert result.verdict == "poorly constrained"
    assert "too few" in result.reasons[0]


def test_frames_are_compared_a_set_time_apart_at_any_rate():
    from calib.motion import frame_gap

    assert frame_gap(np.arange(10) * 33_333_333, 1 / 6) == 5  # 30 fps
    assert frame_gap(np.arange(10) * 33_333_333) == 2  # the default span
    assert frame_gap(np.arange(10) * 100_000_000, 1 / 6) == 2  # 10 Hz (KITTI)
    assert frame_gap(np.arange(10) * 500_000_000, 1 / 6) == 1  # 2 Hz: neighbours
    assert frame_gap(np.array([0])) == 1
