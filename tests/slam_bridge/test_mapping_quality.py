"""The fallback mapper's verdict on its trajectory (slam_bridge.mapping_quality)."""

from __future__ import annotations

import numpy as np

from slam_bridge.mapping_quality import judge_mapping


def _straight(n: int = 50, step: float = 0.3) -> np.ndarray:
    return np.column_stack([np.arange(n) * step, np.zeros(n), np.zeros(n)])


def _judge(raw: np.ndarray, static: np.ndarray, dynamic: float, weakest: float = 0.25):
    n = len(static)
    directions = np.tile([0.0, 1.0, 0.0], (n, 1))
    return judge_mapping(
        raw, static, dynamic, np.full(n, weakest), directions, np.full(n, 0.01), np.full(n, 0.9)
    )


def test_a_well_constrained_static_run_is_ok() -> None:
    quality = _judge(_straight(), _straight(), 0.001)
    assert quality.verdict == "ok" and quality.reasons == []
    assert quality.dynamic_shift_m == 0.0 and quality.weakest_direction is None


def test_traffic_that_pulled_the_registration_is_doubtful() -> None:
    static = _straight()
    raw = static * [0.95, 1.0, 1.0]  # the all-points run came up 5 % short: 0.74 m at the end
    quality = _judge(raw, static, 0.3)
    assert quality.verdict == "doubtful"
    assert "30.0 % of the points moved" in quality.reasons[0] and "0.74 m" in quality.reasons[0]
    # The same difference with (almost) nothing moving comes from de-skewing, not from traffic.
    assert _judge(raw, static, 0.001).verdict == "ok"


def test_degenerate_sweeps_name_the_weak_direction() -> None:
    quality = _judge(_straight(), _straight(), 0.0, weakest=0.01)
    assert quality.verdict == "doubtful" and quality.degenerate_fraction == 1.0
    assert np.allclose(np.abs(quality.weakest_direction), [0.0, 1.0, 0.0])
    assert "barely constrain translation" in quality.reasons[0]
