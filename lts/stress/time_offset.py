"""Time-offset stress area: :func:`~calib.time_offset.estimate_time_offset` on angular-velocity
signals with no, tiny or strong turning, planar or 3-axis, little overlap and heavy noise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.time_offset import estimate_time_offset


@dataclass(frozen=True)
class TimeOffsetCase:
    """Angular-velocity signals for :func:`~calib.time_offset.estimate_time_offset`.

    ``motion``: rad/s amplitude of the turning (0: none); ``overlap``: fraction of the camera
    span the LiDAR signal covers; ``axes``: 1 (planar turning) or 3; ``offset_s``: the true one;
    ``noise``: rad/s standard deviation of the noise added to both signals; ``seed``: its seed.
    """

    motion: float
    overlap: float
    axes: int
    offset_s: float
    noise: float
    seed: int


def check_time_offset(case: TimeOffsetCase) -> list[str]:
    """Either ``poorly constrained`` or an ``ok`` offset whose error is within five of its own
    standard deviations (1 ms at least): never an ``ok`` answer that its uncertainty does not
    cover, never NaN with ``ok``."""
    rng = np.random.default_rng(case.seed)
    t_cam = np.arange(0.0, 12.0, 1 / 15)
    t_lidar = np.arange(0.0, 12.0 * case.overlap, 1 / 200) + 12.0 * (1 - case.overlap) / 2

    def w(t: np.ndarray) -> np.ndarray:
        s = case.motion * np.c_[np.sin(1.3 * t), 0.5 * np.cos(0.7 * t), np.sin(2.1 * t + 1)]
        if case.axes == 1:
            s[:, :2] = 0
        return s

    w_cam = w(t_cam - case.offset_s) + case.noise * rng.normal(size=(len(t_cam), 3))
    w_lidar = w(t_lidar) + case.noise * rng.normal(size=(len(t_lidar), 3))
    r = estimate_time_offset(t_cam, w_cam, t_lidar, w_lidar)
    allowed = max(1e-3, 5 * r.std_s)
    if r.verdict == "ok" and not (
        math.isfinite(r.time_offset_s) and abs(r.time_offset_s - case.offset_s) <= allowed
    ):
        return [f"verdict ok with offset {r.time_offset_s} ± {r.std_s} (truth {case.offset_s})"]
    if r.verdict not in ("ok", "poorly constrained"):
        return [f"verdict {r.verdict!r}"]
    return []


def random_time_offset_case(rng: np.random.Generator) -> TimeOffsetCase:
    """A random :class:`TimeOffsetCase`: motion from none to 1 rad/s, 0.4-100 % overlap, 1 or 3
    axes, an offset within 0.1 s, noise up to 0.3 rad/s."""
    return TimeOffsetCase(
        motion=float(rng.choice([0.0, 1e-3, 0.05, 1.0])),
        overlap=float(rng.choice([1.0, 0.5, 0.05, 0.004])),
        axes=int(rng.choice([1, 3])),
        offset_s=float(rng.uniform(-0.1, 0.1)),
        noise=float(rng.choice([0.0, 0.01, 0.3])),
        seed=int(rng.integers(2**31)),
    )


def stress_time_offset(rng: np.random.Generator) -> tuple[list[str], bool]:
    """One random case through :func:`check_time_offset`: its problems, and ``False``."""
    return check_time_offset(random_time_offset_case(rng)), False
