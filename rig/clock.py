"""Online device→host clock estimate: offset and drift from (t_device, t_host) pairs.

Each pair is a device stamp and the host time the message arrived. Arrival lags the true host
time of the stamp by a transfer delay that is never negative, so the pairs lie on or above the
line ``t_host - t_device = offset + drift * t_device``. The estimate is the edge of the *lower
convex hull* of recent pairs that minimises the summed delay (the linear-programming clock fit of
Moon, Skelly & Towsley, 1999): it follows the fastest transfers and ignores jitter and late
packets, which a least-squares fit would average in.
"""

from __future__ import annotations

from collections import deque
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class ClockEstimate:
    """Device→host mapping ``t_host = t_device + offset_ns + drift_ppm * 1e-6 * (t_device - ref_device_ns)``.

    Attributes:
        offset_ns: host minus device time at ``ref_device_ns`` (the newest pair's device time).
        drift_ppm: how much faster the host clock runs than the device clock, parts per million.
        n_pairs: pairs in the window the fit used.
        median_delay_ns: median of the pairs' height above the fitted line (transfer jitter).
    """

    offset_ns: float
    drift_ppm: float
    ref_device_ns: int
    n_pairs: int
    median_delay_ns: float

    def to_host(self, t_device: int) -> int:
        dt = t_device - self.ref_device_ns
        return int(t_device) + round(self.offset_ns + self.drift_ppm * 1e-6 * dt)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def lower_hull(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the lower convex hull of points sorted by ``x`` (``(N,)`` each), left to right."""
    hull: list[int] = []
    for i in range(len(x)):
        while len(hull) >= 2:
            a, b = hull[-2], hull[-1]
            cross = (x[b] - x[a]) * (y[i] - y[a]) - (y[b] - y[a]) * (x[i] - x[a])
            if cross > 0:
                break
            hull.pop()
        hull.append(i)
    return np.asarray(hull, dtype=np.int64)


def fit_lower_envelope(t_device: np.ndarray, t_host: np.ndarray) -> ClockEstimate:
    """Fit the clock line under ``(N,)`` int64 pairs (N ≥ 1)."""
    order = np.argsort(t_device, kind="stable")
    dev = np.asarray(t_device, dtype=np.int64)[order]
    host = np.asarray(t_host, dtype=np.int64)[order]
    ref = int(dev[-1])
    x = (dev - ref).astype(np.float64)
    y = (host - dev).astype(np.float64)
    hull = lower_hull(x, y)
    slope = 0.0
    if len(hull) >= 2:
        # The LP optimum (min total height above the line) lies on the hull edge spanning mean(x).
        k = int(np.clip(np.searchsorted(x[hull], x.mean()), 1, len(hull) - 1))
        a, b = hull[k - 1], hull[k]
        slope = (y[b] - y[a]) / (x[b] - x[a])
        intercept = y[a] - slope * x[a]
    else:
        intercept = float(y.min())
    delay = y - (intercept + slope * x)
    return ClockEstimate(float(intercept), float(slope * 1e6), ref, len(x), float(np.median(delay)))


class ClockEstimator:
    """Keeps the recent pairs of one device and refits the envelope every ``refit_every`` pairs.

    Args:
        window_s: pairs older than this (device time) leave the fit.
        max_pairs: at most this many pairs are kept.
        min_pairs: :meth:`estimate` is None until this many pairs arrived.
        refit_every: pairs between refits (the fit is O(N) in Python).
    """

    def __init__(
        self, window_s: float = 60.0, max_pairs: int = 3000, min_pairs: int = 10, refit_every: int = 10
    ) -> None:
        self.window_ns = int(window_s * 1e9)
        self.min_pairs = min_pairs
        self.refit_every = refit_every
        self._pairs: deque[tuple[int, int]] = deque(maxlen=max_pairs)
        self._since_fit = 0
        self._estimate: ClockEstimate | None = None

    def reset(self) -> None:
        """Forget every pair (the device restarted its clock)."""
        self._pairs.clear()
        self._since_fit = 0
        self._estimate = None

    def add(self, t_device: int, t_host: int) -> None:
        self._pairs.append((int(t_device), int(t_host)))
        while self._pairs and self._pairs[-1][0] - self._pairs[0][0] > self.window_ns:
            self._pairs.popleft()
        self._since_fit += 1
        if len(self._pairs) >= self.min_pairs and (
            self._estimate is None or self._since_fit >= self.refit_every
        ):
            self._refit()

    def _refit(self) -> None:
        pairs = np.asarray(self._pairs, dtype=np.int64)
        self._estimate = fit_lower_envelope(pairs[:, 0], pairs[:, 1])
        self._since_fit = 0

    def estimate(self) -> ClockEstimate | None:
        """The current estimate (refitted on the newest pairs), or None before ``min_pairs``."""
        if len(self._pairs) >= self.min_pairs and self._since_fit:
            self._refit()
        return self._estimate

    def to_host(self, t_device: int, fallback: int) -> int:
        """``t_device`` on the host clock, or ``fallback`` while there is no estimate yet."""
        return fallback if self._estimate is None else self._estimate.to_host(t_device)
