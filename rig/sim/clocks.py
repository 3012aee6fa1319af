"""Simulated time: a host clock and device clocks with offset and drift.

True time ``t`` (seconds from the start of the run) maps to
- a device's stamp ``offset_s + (1 + drift_ppm·1e-6) · t`` on that device's own clock, and
- the host stamp ``HOST_START_NS + (t + latency_s)``: when the host timestamps the data.

After mapping each sensor's device stamps to host time (a linear fit), the camera–LiDAR time
offset that remains is the latency difference: ``time_offset_s = camera latency − LiDAR latency``
is what to add to LiDAR times to get camera times of the same instant (the calib.yaml convention).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

#: Host monotonic clock reading at the start of a simulated run (ns).
HOST_START_NS = 1_000_000_000_000
#: Host stamping latency of the sensor that is not behind (s).
BASE_LATENCY_S = 0.010


@dataclass(frozen=True)
class SensorClock:
    """A device clock (``offset_s``, ``drift_ppm``) and the host stamping latency ``latency_s``."""

    offset_s: float
    drift_ppm: float
    latency_s: float

    def device_ns(self, t_s: np.ndarray) -> np.ndarray:
        """Device stamps ``(N,)`` int64 ns at true times ``t_s`` ``(N,)``."""
        t = np.asarray(t_s, dtype=np.float64)
        return np.round(self.offset_s * 1e9).astype(np.int64) + np.round(
            t * (1.0 + self.drift_ppm * 1e-6) * 1e9
        ).astype(np.int64)

    def host_ns(self, t_s: np.ndarray) -> np.ndarray:
        """Host stamps ``(N,)`` int64 ns at true times ``t_s`` ``(N,)``."""
        return HOST_START_NS + np.round((np.asarray(t_s, dtype=np.float64) + self.latency_s) * 1e9).astype(
            np.int64
        )

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def rig_clocks(rng: np.random.Generator, time_offset_s: float) -> tuple[SensorClock, SensorClock]:
    """Seeded camera and LiDAR clocks whose host latencies differ by ``time_offset_s``.

    The IMU is built into the LiDAR and shares its clock.
    """
    cam_latency = BASE_LATENCY_S + max(time_offset_s, 0.0)
    lidar_latency = BASE_LATENCY_S + max(-time_offset_s, 0.0)
    camera = SensorClock(float(rng.uniform(100.0, 10_000.0)), float(rng.uniform(-40.0, 40.0)), cam_latency)
    lidar = SensorClock(float(rng.uniform(100.0, 10_000.0)), float(rng.uniform(-40.0, 40.0)), lidar_latency)
    return camera, lidar
