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


def fit_lower_envelope(
    t_device: np.ndarray,
    t_host: np.ndarray,
    min_span_s: float = 5.0,
    offset_window_s: float = 3.0,
    max_drift_ppm: float = 1000.0,
) -> ClockEstimate:
    """Fit the clock line under ``(N,)`` int64 pairs (N ≥ 1).

    Over less than ``min_span_s`` of device time, or when the slope comes out beyond
    ``max_drift_ppm`` (a burst of queued packets at start-up), only the offset is fitted: the
    lowest pair of the last ``offset_window_s``. Over a short span a drift cannot be told from
    jitter (3 ms of jitter over 1 s is 3000 ppm), and extrapolating a wrong one is worse than
    ignoring it (50 ppm over a 3 s window is 0.15 ms).
    """
    order = np.argsort(t_device, kind="stable")
    dev = np.asarray(t_device, dtype=np.int64)[order]
    host = np.asarray(t_host, dtype=np.int64)[order]
    ref = int(dev[-1])
    x = (dev - ref).astype(np.float64)
    y = (host - dev).astype(np.float64)
    hull = lower_hull(x, y)
    slope = 0.0
    recent = x >= x[-1] - offset_window_s * 1e9
    intercept = float(y[recent].min())
    if len(hull) >= 2 and x[-1] - x[0] >= min_span_s * 1e9:
        # The LP optimum (min total height above the line) lies on the hull edge spanning mean(x).
        k = int(np.clip(np.searchsorted(x[hull], x.mean()), 1, len(hull) - 1))
        a, b = hull[k - 1], hull[k]
        slope = (y[b] - y[a]) / (x[b] - x[a])
        intercept = y[a] - slope * x[a]
        if abs(slope) * 1e6 > max_drift_ppm:
            slope, intercept = 0.0, float(y[recent].min())
    delay = y - (intercept + slope * x)
    return ClockEstimate(float(intercept), float(slope * 1e6), ref, len(x), float(np.median(delay)))


class ClockEstimator:
    """Keeps the recent pairs of one device and refits the envelope now and then.

    Only the lowest pair (least delay) of each ``bin_s`` of device time is kept: the others cannot
    be on the lower envelope's fit, and a 2000 packets/s stream then costs no more than a camera.

    Args:
        window_s: pairs older than this (device time) leave the fit.
        bin_s: device-time bin within which only the fastest pair is kept.
        min_pairs: :meth:`estimate` is None until this many bins hold pairs.
        refit_s: device time between refits on :meth:`add` (the fit is O(N) in Python).
        min_span_s: device time the pairs must span before a drift is fitted (else offset only).
    """

    def __init__(
        self,
        window_s: float = 60.0,
        bin_s: float = 0.02,
        min_pairs: int = 10,
        refit_s: float = 0.25,
        min_span_s: float = 5.0,
    ) -> None:
        self.min_span_s = min_span_s
        self.window_ns = int(window_s * 1e9)
        self.bin_ns = max(1, int(bin_s * 1e9))
        self.min_pairs = min_pairs
        self.refit_ns = int(refit_s * 1e9)
        self._pairs: deque[tuple[int, int, int]] = deque()  # (bin, t_device, t_host)
        self._fitted_at: int | None = None
        self._stale = False
        self._estimate: ClockEstimate | None = None

    def reset(self) -> None:
        """Forget every pair (the device restarted its clock)."""
        self._pairs.clear()
        self._fitted_at = None
        self._stale = False
        self._estimate = None

    def add(self, t_device: int, t_host: int) -> None:
        t_device, t_host = int(t_device), int(t_host)
        b = t_device // self.bin_ns
        last = self._pairs[-1] if self._pairs else None
        if last is not None and last[0] == b:
            if t_host - t_device < last[2] - last[1]:
                self._pairs[-1] = (b, t_device, t_host)
        else:
            self._pairs.append((b, t_device, t_host))
        while self._pairs and t_device - self._pairs[0][1] > self.window_ns:
            self._pairs.popleft()
        self._stale = True
        due = self._fitted_at is None or t_device - self._fitted_at >= self.refit_ns
        if len(self._pairs) >= self.min_pairs and due:
            self._refit()

    def _refit(self) -> None:
        pairs = np.asarray(self._pairs, dtype=np.int64)
        self._estimate = fit_lower_envelope(pairs[:, 1], pairs[:, 2], min_span_s=self.min_span_s)
        self._fitted_at = int(pairs[:, 1].max())
        self._stale = False

    def estimate(self) -> ClockEstimate | None:
        """The current estimate (refitted on the newest pairs), or None before ``min_pairs``."""
        if len(self._pairs) >= self.min_pairs and self._stale:
            self._refit()
        return self._estimate

    def latest(self) -> ClockEstimate | None:
        """The estimate of the last refit, without refitting: :meth:`add` refits every ``refit_s``
        of device time, so this is cheap enough to ask per message (a refit per message of a
        200 Hz IMU took a whole core and starved the reading of a LiDAR's packets)."""
        return self._estimate

    def to_host(self, t_device: int, fallback: int) -> int:
        """``t_device`` on the host clock, or ``fallback`` while there is no estimate yet."""
        return fallback if self._estimate is None else self._estimate.to_host(t_device)

    def span_ns(self) -> int:
        """Device time covered by the kept pairs."""
        return self._pairs[-1][1] - self._pairs[0][1] if self._pairs else 0


class HostStamper:
    """Holds device-stamped messages until the clock estimate has ``warmup_s`` of pairs behind it,
    then sets each one's ``t_host`` from the estimate, in arrival order.

    Early estimates rest on few pairs, often from a burst queued while the host started up; stamps
    from them would jump back once faster pairs arrive. Messages held longer than ``max_hold_s``
    (host time) are released with their arrival-based ``t_host``, so memory stays bounded.
    """

    def __init__(self, clock: ClockEstimator, warmup_s: float = 1.0, max_hold_s: float = 5.0) -> None:
        self.clock = clock
        self.warmup_ns = int(warmup_s * 1e9)
        self.max_hold_ns = int(max_hold_s * 1e9)
        self._held: list[Any] = []

    def ready(self) -> bool:
        return self.clock.latest() is not None and self.clock.span_ns() >= self.warmup_ns

    def push(self, message: Any) -> list[Any]:
        """Queue ``message`` (``t_device`` set, ``t_host`` = arrival fallback); returns those released."""
        self._held.append(message)
        if self.ready():
            out, self._held = self._held, []
            for m in out:
                m.t_host = self.clock.to_host(int(m.t_device), fallback=m.t_host)
            return out
        if self._held[-1].t_host - self._held[0].t_host > self.max_hold_ns:
            out, self._held = self._held, []
            return out
        return []

    def flush(self) -> list[Any]:
        """Release every held message, stamped from the estimate as it is (at the end of a recording)."""
        out, self._held = self._held, []
        for m in out:
            m.t_host = self.clock.to_host(int(m.t_device), fallback=m.t_host)
        return out


#: ``clock:`` keys accepted in ``rig.yaml`` (the :class:`ClockEstimator` arguments).
CLOCK_OPTIONS = ("window_s", "bin_s", "min_pairs", "refit_s", "min_span_s")
