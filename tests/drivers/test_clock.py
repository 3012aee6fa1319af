"""Device→host clock estimate: lower envelope under one-sided transfer jitter."""

import numpy as np
import pytest

from rig.clock import ClockEstimator, fit_lower_envelope


@pytest.mark.parametrize("jitter", ["uniform", "exponential"])
def test_50ppm_drift_3ms_jitter_offset_error_below_half_ms(jitter: str) -> None:
    rng = np.random.default_rng(1)
    t_true = 5e9 + np.arange(0, 20, 1 / 30) * 1e9  # host clock at capture, 30 Hz for 20 s
    dev = np.round(t_true * (1 + 50e-6) + 7_123_456_789).astype(np.int64)  # device runs 50 ppm fast
    delay = rng.uniform(0, 3e6, t_true.size) if jitter == "uniform" else rng.exponential(3e6, t_true.size)
    base = 0.2e6  # fixed part of the latency: indistinguishable from the offset, so part of the truth
    host = np.round(t_true + base + delay).astype(np.int64)
    est = ClockEstimator(window_s=60)
    errors = []
    for i, (d, h) in enumerate(zip(dev, host, strict=True)):
        est.add(int(d), int(h))
        if i >= 60:  # after 2 s of pairs
            errors.append(est.estimate().to_host(int(d)) - (t_true[i] + base))
    errors = np.abs(errors)
    assert errors.max() < 0.5e6, errors.max()
    assert abs(est.estimate().drift_ppm + 50) < 5  # host runs ~50 ppm slower than the device


def test_exact_line_and_window() -> None:
    dev = np.arange(100, dtype=np.int64) * 10_000_000
    fit = fit_lower_envelope(dev, dev + 1_000_000)
    assert fit.to_host(5_000_000_000) == 5_001_000_000 and abs(fit.drift_ppm) < 1e-9
    est = ClockEstimator(window_s=0.5, min_pairs=3, bin_s=0.02)
    assert est.estimate() is None and est.to_host(5, fallback=9) == 9
    for d in dev:  # 10 ms apart: two pairs per 20 ms bin, the faster one kept
        est.add(int(d), int(d) + 1_000)
        est.add(int(d) + 1, int(d) + 1 + 500)
    fit = est.estimate()
    assert fit.n_pairs == 25  # a 0.5 s window of 20 ms bins
    assert fit.to_host(990_000_000) == 990_000_500
    est.reset()
    assert est.estimate() is None
