"""When the ICP pose of a sweep that was not de-skewed holds (calib.motion.information_time)."""

from __future__ import annotations

import numpy as np
import pytest

from calib.motion import information_time


def _room_sweep(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points ``(N, 3)`` on the walls of a 4 × 10 m room seen from (1, 1) m off its centre, their times
    ``(N,)`` (one 0.1 s turn of azimuth) and the walls' normals ``(N, 3)``."""
    azimuth = np.sort(rng.uniform(0, 2 * np.pi, 4000))
    d = np.column_stack([np.cos(azimuth), np.sin(azimuth), rng.uniform(-0.3, 0.3, len(azimuth))])
    half, centre = np.array([5.0, 2.0]), np.array([1.0, 1.0])
    # Distance along each ray to the nearest of the four walls x = ±5, y = ±2 (room frame).
    with np.errstate(divide="ignore"):
        steps = (np.sign(d[:, :2]) * half - centre) / d[:, :2]
    axis = np.argmin(steps, axis=1)
    points = d * steps[np.arange(len(d)), axis][:, None]
    normals = np.zeros_like(points)
    normals[np.arange(len(d)), axis] = 1.0
    return points, azimuth / (2 * np.pi) * 0.1, normals


def test_weights_points_by_rotational_information() -> None:
    points, times, normals = _room_sweep(np.random.default_rng(0))
    source = points[::3]
    weight = np.sum(np.cross(source, normals[::3]) ** 2, axis=1)
    expected = np.average(times[::3], weights=weight)
    # (Within 1 ms: the estimated normals are off at the room's corners.)
    assert information_time(source, points, times) == pytest.approx(expected, abs=1e-3)
    # Not the plain mean: the far wall (y = -2, three quarters into the turn) weighs more.
    assert expected - times[::3].mean() > 5e-3


def test_one_instant_sweep() -> None:
    points, _, _ = _room_sweep(np.random.default_rng(1))
    assert information_time(points[::5], points, np.full(len(points), 0.03)) == pytest.approx(0.03)
