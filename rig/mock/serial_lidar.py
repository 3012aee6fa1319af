"""A fake serial 2D LiDAR on a pseudo-terminal, speaking LD06 or RPLIDAR bytes in real time.

The driver opens :attr:`link` (a symlink to the pty's slave, like ``/dev/serial/by-id/...``).
Options: a rate of corrupted bytes (one random bit flipped), and an *unplug*: at ``unplug_at_s``
the pty is closed (the driver's reads fail as with a pulled USB cable) and after ``unplug_for_s``
a new pty appears behind the same link.
"""

from __future__ import annotations

import os
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rig.drivers import ld06_protocol as ld
from rig.drivers import rplidar_protocol as rp
from rig.mock.device_clock import DriftingClock
from rig.mock.pacing import sleep_until

#: ``revolution(t_rel_ns) -> (ranges_m (B,), intensity (B,))`` for B angle bins over 360 degrees.
RevolutionSource = Callable[[int], tuple[np.ndarray, np.ndarray]]


class FakeSerialLidar:
    def __init__(
        self,
        link: str | Path,
        revolution: RevolutionSource,
        protocol: str = "ld06",
        rate_hz: float = 10.0,
        corrupt_rate: float = 0.0,
        unplug_at_s: float | None = None,
        unplug_for_s: float = 1.0,
        clock: DriftingClock | None = None,
        seed: int = 0,
    ) -> None:
        if protocol not in ("ld06", "rplidar"):
            raise ValueError(f"unknown protocol {protocol!r}; expected ld06 or rplidar")
        self.link = Path(link)
        self.revolution = revolution
        self.protocol = protocol
        self.rate_hz = rate_hz
        self.corrupt_rate = corrupt_rate
        self.unplug_at_s = unplug_at_s
        self.unplug_for_s = unplug_for_s
        self.clock_spec = clock or DriftingClock(drift_ppm=30.0, offset_ns=0)
        self._rng = np.random.default_rng(seed)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._master = -1
        self._slave = -1
        self.corrupted_packets = 0
        self.packets_sent = 0
        self.revolutions_sent = 0
        self.unplugged: list[tuple[int, int]] = []
        self.info = rp.DeviceInfo(model=0x18, firmware=(1, 29), hardware=7, serial="00" * 15 + "2A")

    # -- pty plumbing ---------------------------------------------------------------------------
    def _plug(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no CR/LF translation: bytes pass unchanged
        os.set_blocking(self._master, False)
        tmp = self.link.with_name(self.link.name + ".tmp")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(self._slave))
        tmp.replace(self.link)

    def _unplug(self) -> None:
        self.link.unlink(missing_ok=True)
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1

    def _send(self, data: bytes) -> None:
        if self.corrupt_rate > 0:
            buf = np.frombuffer(data, dtype=np.uint8).copy()
            hit = np.flatnonzero(self._rng.random(buf.size) < self.corrupt_rate)
            buf[hit] ^= (1 << self._rng.integers(0, 8, hit.size)).astype(np.uint8)
            data = buf.tobytes()
            size = ld.PACKET_SIZE if self.protocol == "ld06" else rp.NODE_SIZE
            self.corrupted_packets += len(np.unique(hit // size))
        try:
            os.write(self._master, data)
        except BlockingIOError:
            pass  # nobody reads: the bytes are lost, as on a real UART
        except OSError:
            pass  # the reader hung up

    # -- lifecycle -------------------------------------------------------------------------------
    def start(self) -> FakeSerialLidar:
        self._plug()
        self._thread = threading.Thread(target=self._run, name=f"fake-{self.protocol}", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5)
        self._unplug()

    def __enter__(self) -> FakeSerialLidar:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run(self) -> None:
        t0 = time.monotonic_ns()
        clock = DriftingClock(self.clock_spec.drift_ppm, self.clock_spec.offset_ns, t0)
        period_ns = round(1e9 / self.rate_hz)
        scanning = self.protocol == "ld06"  # LD06 streams from power-on; RPLIDAR waits for SCAN
        plugged_at = t0
        requests = bytearray()
        k = 0
        while not self._stop.is_set():
            t_rev = t0 + k * period_ns
            if self.unplug_at_s is not None and t_rev - t0 >= self.unplug_at_s * 1e9 and not self.unplugged:
                lost = time.monotonic_ns()
                self._unplug()
                if not sleep_until(lost + int(self.unplug_for_s * 1e9), self._stop):
                    return
                self._plug()
                back = time.monotonic_ns()
                self.unplugged.append((lost, back))
                plugged_at = back
                scanning = self.protocol == "ld06"
                k = (back - t0) // period_ns + 1
                continue
            if self.protocol == "rplidar":
                was_scanning = scanning
                scanning = self._answer(requests, scanning)
                if scanning and not was_scanning:
                    k = (time.monotonic_ns() - t0) // period_ns + 1
                    continue
                if not scanning:
                    if self._stop.wait(0.005):
                        return
                    continue
            ranges, intensity = self.revolution(t_rev - t0)
            if self.protocol == "ld06":
                ok = self._ld06_revolution(ranges, intensity, t_rev, period_ns, clock, plugged_at)
            else:
                ok = self._rplidar_revolution(ranges, intensity, t_rev, period_ns)
            if not ok:
                return
            self.revolutions_sent += 1
            k += 1

    def _ld06_revolution(
        self,
        ranges: np.ndarray,
        intensity: np.ndarray,
        t_rev: int,
        period_ns: int,
        clock: DriftingClock,
        boot: int,
    ) -> bool:
        n = len(ranges)
        per = ld.POINTS_PER_PACKET
        packets = n // per
        speed = round(360.0 * self.rate_hz)
        step = 360.0 / n
        for j in range(packets):
            t_pkt = t_rev + j * period_ns // packets
            if not sleep_until(t_pkt, self._stop):
                return False
            sl = slice(j * per, (j + 1) * per)
            stamp_ms = (clock.device_ns(t_pkt) - clock.device_ns(boot)) // 1_000_000
            data = ld.encode_packet(
                speed,
                j * per * step,
                ((j + 1) * per - 1) * step,
                np.round(ranges[sl] * 1000),
                intensity[sl],
                stamp_ms,
            )
            self._send(data)
            self.packets_sent += 1
        return True

    def _rplidar_revolution(
        self, ranges: np.ndarray, intensity: np.ndarray, t_rev: int, period_ns: int
    ) -> bool:
        n = len(ranges)
        batches = 20
        per = n // batches
        angles = np.arange(n) * 360.0 / n
        for j in range(batches):
            if not sleep_until(t_rev + j * period_ns // batches, self._stop):
                return False
            sl = slice(j * per, n if j == batches - 1 else (j + 1) * per)
            start = np.zeros(sl.stop - sl.start, dtype=bool)
            start[0] = j == 0
            quality = np.where(ranges[sl] > 0, 47, 0)
            self._send(rp.encode_nodes(start, quality, angles[sl], ranges[sl] * 1000))
            self.packets_sent += len(start)
        return True

    def _answer(self, requests: bytearray, scanning: bool) -> bool:
        """Answer RPLIDAR requests waiting on the pty; returns whether scan mode is on."""
        try:
            requests += os.read(self._master, 256)
        except (BlockingIOError, OSError):
            return scanning
        while len(requests) >= 2:
            if requests[0] != rp.SYNC1:
                del requests[0]
                continue
            cmd = requests[1]
            del requests[:2]
            if cmd == rp.CMD_STOP:
                scanning = False
            elif cmd == rp.CMD_GET_HEALTH:
                os.write(
                    self._master,
                    rp.encode_descriptor(*rp.HEALTH_DESCRIPTOR)
                    + rp.encode_health(rp.DeviceHealth("good", 0)),
                )
            elif cmd == rp.CMD_GET_INFO:
                os.write(self._master, rp.encode_descriptor(*rp.INFO_DESCRIPTOR) + rp.encode_info(self.info))
            elif cmd == rp.CMD_SCAN:
                os.write(self._master, rp.encode_descriptor(*rp.SCAN_DESCRIPTOR))
                scanning = True
        return scanning
