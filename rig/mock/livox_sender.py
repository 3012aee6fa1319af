"""A fake Livox Mid-360: sends SDK2 point and IMU packets over UDP (127.0.0.1) in real time.

Each scan's points are sorted by time and cut into packets of ``points_per_packet`` (96, as the
sensor does); a packet leaves when its last point has been "measured". Timestamps come from a
drifting device clock.
"""

from __future__ import annotations

import heapq
import socket
import threading
import time
from collections.abc import Iterator

import numpy as np

from rig.drivers import livox_protocol as lp
from rig.messages import ImuSample, Scan
from rig.mock.device_clock import DriftingClock
from rig.mock.pacing import sleep_until


class FakeLivox:
    def __init__(
        self,
        scans: Iterator[tuple[int, Scan]],
        imu: Iterator[tuple[int, ImuSample]] | None = None,
        address: str = "127.0.0.1",
        point_port: int = lp.POINT_PORT,
        imu_port: int = lp.IMU_PORT,
        clock: DriftingClock | None = None,
        points_per_packet: int = 96,
    ) -> None:
        self.scans, self.imu_stream = scans, imu
        self.address, self.point_port, self.imu_port = address, point_port, imu_port
        self.clock_spec = clock or DriftingClock(drift_ppm=-20.0, offset_ns=5_000_000_000)
        self.points_per_packet = points_per_packet
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.packets_sent = 0
        self.scans_sent = 0
        self.imu_sent = 0

    def start(self) -> FakeLivox:
        self._thread = threading.Thread(target=self._run, name="fake-livox", daemon=True)
        self._thread.start()
        return self

    @property
    def sending(self) -> bool:
        """Whether the sender still runs (it ends when its streams end, or on :meth:`stop`)."""
        return self._thread is not None and self._thread.is_alive()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5)

    def __enter__(self) -> FakeLivox:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _scan_packets(
        self, t_capture: int, scan: Scan, clock: DriftingClock, frame: int
    ) -> list[tuple[int, bytes]]:
        order = np.argsort(scan.point_time_s, kind="stable")
        t_pts = t_capture + np.round(np.asarray(scan.point_time_s, dtype=np.float64)[order] * 1e9).astype(
            np.int64
        )
        pts = np.asarray(scan.points, dtype=np.float64)[order]
        refl = np.asarray(scan.intensity)[order]
        out = []
        for a in range(0, len(pts), self.points_per_packet):
            b = min(a + self.points_per_packet, len(pts))
            stamp = clock.device_ns(int(t_pts[a]))
            interval = int(t_pts[b - 1] - t_pts[a]) * (b - a) // max(b - a - 1, 1)
            out.append((int(t_pts[b - 1]), lp.encode_points(pts[a:b], refl[a:b], stamp, interval, 0, frame)))
        if not out:  # an empty scan still marks time: one packet with no points
            out.append(
                (
                    t_capture,
                    lp.encode_points(np.zeros((0, 3)), np.zeros(0), clock.device_ns(t_capture), 0, 0, frame),
                )
            )
        return out

    def _run(self) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        t0 = time.monotonic_ns()
        clock = DriftingClock(self.clock_spec.drift_ppm, self.clock_spec.offset_ns, t0)
        counters = {self.point_port: 0, self.imu_port: 0}
        queue: list[tuple[int, int, int, bytes]] = []  # (due, seq, port, packet with counter 0)
        seq = 0
        next_scan = next(self.scans, None)
        next_imu = next(self.imu_stream, None) if self.imu_stream is not None else None
        try:
            while not self._stop.is_set():
                now = time.monotonic_ns()
                horizon = now + 200_000_000  # prepare what is due in the next 0.2 s
                while next_scan is not None and t0 + next_scan[0] <= horizon:
                    for due, pkt in self._scan_packets(
                        t0 + next_scan[0], next_scan[1], clock, self.scans_sent
                    ):
                        heapq.heappush(queue, (due, seq, self.point_port, pkt))
                        seq += 1
                    self.scans_sent += 1
                    next_scan = next(self.scans, None)
                while next_imu is not None and t0 + next_imu[0] <= horizon:
                    t = t0 + next_imu[0]
                    s = next_imu[1]
                    pkt = lp.encode_imu(s.angular_velocity, s.linear_acceleration, clock.device_ns(t), 0)
                    heapq.heappush(queue, (t, seq, self.imu_port, pkt))
                    seq += 1
                    self.imu_sent += 1
                    next_imu = next(self.imu_stream, None) if self.imu_stream is not None else None
                if not queue:
                    if next_scan is None and next_imu is None:
                        return
                    self._stop.wait(0.01)
                    continue
                if not sleep_until(queue[0][0], self._stop):
                    return
                now = time.monotonic_ns()
                while queue and queue[0][0] <= now:
                    _, _, port, pkt = heapq.heappop(queue)
                    sock.sendto(_with_counter(pkt, counters[port]), (self.address, port))
                    counters[port] = (counters[port] + 1) & 0xFFFF
                    self.packets_sent += 1
        finally:
            sock.close()


def _with_counter(packet: bytes, udp_cnt: int) -> bytes:
    """``packet`` with its ``udp_cnt`` field set (the field is outside the CRC-32)."""
    return packet[:7] + udp_cnt.to_bytes(2, "little") + packet[9:]
