"""A device clock that drifts against the host clock (for mock devices)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class DriftingClock:
    """``t_device = offset_ns + (t_host - host_origin_ns) * (1 + drift_ppm * 1e-6)``."""

    drift_ppm: float = 50.0
    offset_ns: int = 1_000_000_000
    host_origin_ns: int = 0

    def device_ns(self, t_host: int) -> int:
        dt = t_host - self.host_origin_ns
        return self.offset_ns + dt + round(dt * self.drift_ppm * 1e-6)
