"""A fake OAK: delivers frames (and IMU samples) in real time, stamped by a drifting device clock.

Implements :class:`rig.drivers.oak.OakSource`, so :class:`rig.drivers.oak.OakDriver` runs on it
unchanged. Like depthai without time sync, it gives only the device stamp: the driver must
estimate the host time itself. Arrival = capture + ``latency_ms`` + uniform jitter in
``[0, jitter_ms]``; :attr:`true_capture` keeps each device stamp's true host capture time so tests
can measure the driver's clock error.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator

import numpy as np

from rig.drivers.oak import OakPacket
from rig.messages import Frame, ImuSample
from rig.mock.device_clock import DriftingClock
from rig.mock.pacing import sleep_until


class FakeOakSource:
    def __init__(
        self,
        frames: Iterator[tuple[int, Frame]],
        imu: Iterator[tuple[int, ImuSample]] | None = None,
        clock: DriftingClock | None = None,
        latency_ms: float = 2.0,
        jitter_ms: float = 3.0,
        device_id: str = "FAKE-OAK-0001",
        seed: int = 0,
    ) -> None:
        self._streams = [("image", frames)] + ([("imu", imu)] if imu is not None else [])
        self.clock_spec = clock or DriftingClock()
        self.latency_ns = int(latency_ms * 1e6)
        self.jitter_ns = int(jitter_ms * 1e6)
        self._id = device_id
        self._rng = np.random.default_rng(seed)
        self._stop = threading.Event()
        self._t0 = 0
        self._next: dict[str, tuple[int, Frame | ImuSample] | None] = {}
        self.true_capture: dict[int, int] = {}

    def open(self) -> str:
        import time

        self._t0 = time.monotonic_ns()
        self.clock = DriftingClock(self.clock_spec.drift_ppm, self.clock_spec.offset_ns, self._t0)
        self._next = {name: next(it, None) for name, it in self._streams}
        return self._id

    def _arrival(self, item: tuple[int, Frame | ImuSample]) -> int:
        return self._t0 + item[0] + self.latency_ns

    def get(self, timeout_s: float) -> list[OakPacket]:
        import time

        pending = [(self._arrival(v), name) for name, v in self._next.items() if v is not None]
        if not pending:
            self._stop.wait(timeout_s)
            return []
        due, _ = min(pending)
        limit = time.monotonic_ns() + int(timeout_s * 1e9)
        if not sleep_until(min(due + self.jitter_ns, limit), self._stop):
            return []
        now = time.monotonic_ns()
        out: list[OakPacket] = []
        for name, it in self._streams:
            while (item := self._next[name]) is not None and self._arrival(item) + self.jitter_ns <= now:
                capture = self._t0 + item[0]
                t_dev = self.clock.device_ns(capture)
                self.true_capture[t_dev] = capture
                # the stamp the driver sees as "arrival": capture + latency + jitter (never before now)
                arrival = min(now, capture + self.latency_ns + int(self._rng.uniform(0, self.jitter_ns)))
                msg = item[1]
                if isinstance(msg, Frame):
                    image = msg.image if msg.image.ndim == 3 else np.repeat(msg.image[:, :, None], 3, axis=2)
                    out.append(OakPacket(t_dev, None, arrival, image=image))
                else:
                    out.append(
                        OakPacket(
                            t_dev, None, arrival, gyro=msg.angular_velocity, acc=msg.linear_acceleration
                        )
                    )
                self._next[name] = next(it, None)
        return out

    @property
    def exhausted(self) -> bool:
        """Whether every stream has ended (after :meth:`open`): a scene played once."""
        return bool(self._next) and all(v is None for v in self._next.values())

    def close(self) -> None:
        self._stop.set()
