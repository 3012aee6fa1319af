"""Real-time pacing for mock devices: sleep until a host time, in small steps so stop is prompt."""

from __future__ import annotations

import threading
import time


def sleep_until(t_host_ns: int, stop: threading.Event, step_s: float = 0.05) -> bool:
    """Sleep until ``time.monotonic_ns() >= t_host_ns``; False if ``stop`` was set meanwhile."""
    while True:
        wait = (t_host_ns - time.monotonic_ns()) / 1e9
        if wait <= 0:
            return not stop.is_set()
        if stop.wait(min(wait, step_s)):
            return False
