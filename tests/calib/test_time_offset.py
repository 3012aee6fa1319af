"""Time offset from angular-speed signals: recovery, and refusal on weak or uniform motion."""

from __future__ import annotations

import numpy as np
import pytest

from calib.time_offset import estimate_time_offset


def _turning(t: np.ndarray, rng_seed: int = 0) -> np.ndarray:
    """A smooth angular-speed profile (rad/s) with turns of varying rate."""
    rng = np.random.default_rng(rng_seed)
    freqs = rng.uniform(0.05, 0.6, 6)
    phases = rng.uniform(0, 2 * np.pi, 6)
    return (
        0.4
        + 0.3
        * np.sum([np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs, phases, strict=True)], axis=0)
        / 3
    )


def _signals(offset: float, profile, noise_cam: float = 0.02, noise_imu: float = 0.01):
    """Camera samples at 30 Hz and LiDAR-clock gyro at 200 Hz of one motion; the LiDAR clock
    reads ``offset`` less than the camera clock."""
    rng = np.random.default_rng(1)
    t_true_cam = np.arange(0.0, 20.0, 1 / 30)
    t_true_imu = np.arange(0.0, 20.0, 1 / 200)
    w_cam = profile(t_true_cam) + rng.normal(0, noise_cam, len(t_true_cam))
    w_imu = profile(t_true_imu) + rng.normal(0, noise_imu, len(t_true_imu))
    return t_true_cam + 100.0, w_cam, t_true_imu + 100.0 - offset, w_imu


@pytest.mark.parametrize("offset", [0.015, -0.12, 0.3])
def test_recovers_offset_within_2_ms(offset: float) -> None:
    result = estimate_time_offset(*_signals(offset, _turning))
    assert result.verdict == "ok", result.reasons
    assert abs(result.time_offset_s - offset) < 0.002
    assert result.std_s < 0.005
    assert result.correlation > 0.9


def test_straight_drive_is_refused() -> None:
    result = estimate_time_offset(*_signals(0.02, lambda t: np.zeros_like(t)))
    assert result.verdict == "poorly constrained"
    assert "too weak" in result.reasons[0]
    assert np.isnan(result.time_offset_s)


def test_uniform_turn_is_refused() -> None:
    result = estimate_time_offset(*_signals(0.02, lambda t: np.full_like(t, 0.5)))
    assert result.verdict == "poorly constrained"


def test_too_few_samples_is_refused() -> None:
    t_cam, w_cam, t_imu, w_imu = _signals(0.0, _turning)
    result = estimate_time_offset(t_cam[:5], w_cam[:5], t_imu, w_imu)
    assert result.verdict == "poorly constrained"
    assert "too few" in result.reasons[0]
