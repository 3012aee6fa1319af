"""Livox Mid-360 driver: SDK2 point and IMU packets over UDP, cut into fixed-period scans."""

from __future__ import annotations

import select
import socket

import numpy as np

from rig.clock import ClockEstimator
from rig.drivers import livox_protocol as lp
from rig.drivers.base import DeviceClockDriver, DeviceError, Message, ParseError, now_ns
from rig.messages import ImuSample, Scan


class LivoxDriver(DeviceClockDriver):
    """Receives a Mid-360's UDP stream on ``host``:``point_port`` / ``imu_port``.

    The sensor streams from power-on once configured to send to this host. With ``split="time"``
    points are grouped into scans on a fixed grid of ``scan_period_s`` of device time, anchored
    half a percent of a period before the first packet (so the rate is exact); with
    ``split="frame"`` a scan ends when the header's ``frame_cnt`` changes (the mock sender numbers
    its scans so). ``udp_cnt`` gaps are counted as dropped packets. ``t_host`` comes from
    the online clock estimate, fed with each packet's last-point device time and its arrival.
    """

    kind = "livox"

    def __init__(
        self,
        name: str,
        host: str = "0.0.0.0",
        point_port: int = lp.POINT_PORT,
        imu_port: int | None = lp.IMU_PORT,
        scan_period_s: float = 0.1,
        recv_buffer_bytes: int = 8 << 20,
        split: str = "time",
        clock: ClockEstimator | None = None,
    ) -> None:
        super().__init__(name, clock)
        if split not in ("time", "frame"):
            raise ValueError(f"split must be 'time' or 'frame', got {split!r}")
        self.split = split
        self.host, self.point_port, self.imu_port = host, point_port, imu_port
        self.period_ns = round(scan_period_s * 1e9)
        self.recv_buffer_bytes = recv_buffer_bytes
        self._sockets: list[socket.socket] = []
        self._last_cnt: dict[int, int] = {}
        self._grid0: int | None = None
        self._scan_index = -1
        self._scan_start = 0  # device stamp of the current scan's first packet
        self._scan_arrival = 0  # host arrival of the current scan's first packet
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def open(self) -> None:
        ports = [self.point_port] + ([self.imu_port] if self.imu_port is not None else [])
        try:
            for port in ports:
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, self.recv_buffer_bytes)
                sock.bind((self.host, port))
                sock.setblocking(False)
                self._sockets.append(sock)
        except OSError as exc:
            self.close()
            raise DeviceError(f"cannot listen on {self.host}:{ports}: {exc}") from exc

    @property
    def bound_ports(self) -> list[int]:
        """The ports actually bound (useful when asked for port 0)."""
        return [s.getsockname()[1] for s in self._sockets]

    def device_id(self) -> str:
        port = self.bound_ports[0] if self._sockets else self.point_port
        return f"livox@{self.host}:{port}"

    def read(self, timeout_s: float = 0.1) -> list[Message]:
        if not self._sockets:
            return []
        ready, _, _ = select.select(self._sockets, [], [], timeout_s)
        out: list[Message] = []
        for sock in ready:
            for _ in range(256):  # bounded: a busy stream must not keep read() from returning
                try:
                    data = sock.recv(65536)
                except BlockingIOError:
                    break
                out.extend(self._on_datagram(data, now_ns()))
        return out

    def _on_datagram(self, data: bytes, t_arrival: int) -> list[Message]:
        try:
            p = lp.parse_packet(data)
        except ParseError:
            self.health.crc_errors += 1
            return []
        self.health.packets += 1
        stream = 0 if p.data_type == lp.DATA_IMU else 1
        last = self._last_cnt.get(stream)
        if last is not None:
            self.health.dropped += (p.udp_cnt - last - 1) % 65536
        self._last_cnt[stream] = p.udp_cnt
        self.clock.add(p.timestamp_ns + p.time_interval_ns, t_arrival)
        if p.data_type == lp.DATA_IMU:
            assert p.gyro is not None and p.acc is not None
            self.health.received += 1
            return self.stamper.push(ImuSample(p.gyro, p.acc, t_arrival, p.timestamp_ns, f"{self.name}/imu"))
        out: list[Message] = []
        if self.split == "frame":
            index = p.frame_cnt
        else:
            if self._grid0 is None:  # scan k holds packets stamped in [grid0 + k P, grid0 + (k+1) P)
                self._grid0 = p.timestamp_ns - self.period_ns // 200
            index = (p.timestamp_ns - self._grid0) // self.period_ns
        if index != self._scan_index:
            scan = self._finish()
            if scan is not None:
                out.extend(self.stamper.push(scan))
            self._scan_index, self._scan_start, self._scan_arrival = index, p.timestamp_ns, t_arrival
        self._parts.append((p.points, p.reflectivity, p.timestamp_ns + p.point_offsets_ns()))
        return out

    def drain(self) -> list[Message]:
        """The messages held back, and the scan in progress: at the end of a recording its
        packets are kept as a (possibly partial) scan rather than lost."""
        scan = self._finish()
        held = self.stamper.push(scan) if scan is not None else []
        return held + self.stamper.flush()

    def _finish(self) -> Scan | None:
        if not self._parts:
            return None
        points, refl, t = (np.concatenate(a) for a in zip(*self._parts, strict=True))
        self._parts.clear()
        stamp = self._scan_start
        keep = np.any(points != 0, axis=1)  # (0, 0, 0) = no return
        self.health.received += 1
        return Scan(
            points[keep].astype(np.float32),
            ((t[keep] - stamp) * 1e-9).astype(np.float32),
            refl[keep].astype(np.float32),
            t_host=self._scan_arrival,  # the stamper replaces it from the clock estimate
            t_device=stamp,
            lidar_id=self.name,
        )

    def close(self) -> None:
        for sock in self._sockets:
            sock.close()
        self._sockets.clear()
