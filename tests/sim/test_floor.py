"""The ``floor`` preset: a long corridor whose path stays inside it for as long as it lasts."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from rig.sim.config import SimConfig
from rig.sim.scenes import FLOOR_LEG_M, PRESETS, _floor_centreline
from rig.sim.trajectories import path_motion


def _distance_to_centreline(points: np.ndarray) -> np.ndarray:
    """``(N,)`` distance of ground points ``(N, 2)`` to the floor's corridor centreline."""
    c = _floor_centreline()
    best = np.full(len(points), np.inf)
    for a, b in itertools.pairwise(c):
        ab = b - a
        s = np.clip((points - a) @ ab / (ab @ ab), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - (a + s[:, None] * ab), axis=1))
    return best


@pytest.mark.parametrize("duration", [120.0, 240.0])
def test_the_robot_stays_in_the_corridor(duration):
    preset = PRESETS["floor"]
    motion = path_motion(
        np.array(preset.waypoints), duration, rng=np.random.default_rng(0), carrier="wheeled",
        speed_mps=preset.speed_mps, closed=False,
    )  # fmt: skip
    positions = motion.positions(np.linspace(0.0, duration, 4000))[:, :2]
    assert _distance_to_centreline(positions).max() < 0.5  # the corridor is 2.4 m wide
    travelled = np.linalg.norm(np.diff(positions, axis=0), axis=1).sum()
    assert travelled > FLOOR_LEG_M * duration / 120.0 * 1.5  # 2 minutes cover more than a leg


def test_the_floor_runs_two_minutes_unless_told_otherwise():
    assert SimConfig(preset="floor").duration_s == 120.0
    assert SimConfig(preset="floor", duration_s=30.0).duration_s == 30.0
    assert SimConfig(preset="room").duration_s == 20.0
