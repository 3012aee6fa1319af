"""LDROBOT LD06 / LD19 / STL-27L driver (pyserial): packets → revolutions, device clock → host."""

from __future__ import annotations

import numpy as np

from rig.clock import ClockEstimator
from rig.drivers.base import DeviceClockDriver, Message
from rig.drivers.ld06_protocol import BAUD, PACKET_SIZE, POINTS_PER_PACKET, TIMESTAMP_WRAP_MS, LdStreamParser
from rig.drivers.scan2d import RevolutionAssembler
from rig.drivers.serial_link import SerialLink


class Ld06Driver(DeviceClockDriver):
    """A LD06-family LiDAR on a serial port; it streams from power-on (no commands).

    Scans carry ``t_device`` (the packet timestamps, unwrapped from their 30 s wrap) and ``t_host``
    from the online clock estimate (scans wait in a :class:`HostStamper` for its first second). The
    estimate is fed with each packet's arrival time corrected for serial transfer time (10 bits per
    byte at the model's baud rate).
    """

    kind = "ld06"

    def __init__(
        self,
        name: str,
        port: str,
        model: str = "ld06",
        baud: int | None = None,
        clock: ClockEstimator | None = None,
    ) -> None:
        super().__init__(name, clock)
        if model not in BAUD:
            raise ValueError(f"unknown LDROBOT model {model!r}; expected one of {sorted(BAUD)}")
        self.port = port
        self.link = SerialLink(port, baud or BAUD[model], self.health)
        self.link.on_connect = self._on_connect
        self._reset_stream()

    def _reset_stream(self) -> None:
        self.parser = LdStreamParser()
        self.assembler = RevolutionAssembler(self.name, device_clock=True)
        self._last_raw_ms: int | None = None
        self._wrap_ms = 0
        self._last_start = -1.0

    def _on_connect(self) -> None:
        self._reset_stream()
        self.clock.reset()  # the device clock restarts with the device

    def open(self) -> None:
        self.link.open()

    def device_id(self) -> str:
        return self.port

    def _device_ns(self, raw_ms: int) -> int:
        if self._last_raw_ms is not None and raw_ms < self._last_raw_ms - TIMESTAMP_WRAP_MS // 2:
            self._wrap_ms += TIMESTAMP_WRAP_MS
        self._last_raw_ms = raw_ms
        return (self._wrap_ms + raw_ms) * 1_000_000

    def read(self, timeout_s: float = 0.1) -> list[Message]:
        was_connected = self.link.connected
        data, t_end = self.link.read(timeout_s)
        if was_connected and not self.link.connected:
            self.assembler.discard()
            self.health.dropped += 1  # the revolution in progress is lost
            return self.stamper.flush()  # stamped with the estimate so far: the clock restarts
        if not data:
            return []
        crc_before = self.parser.crc_errors
        packets = self.parser.feed(data)
        self.health.crc_errors += self.parser.crc_errors - crc_before
        last_offset = self.parser.offset - 1
        out: list[Message] = []
        for end_offset, p in packets:
            self.health.packets += 1
            t_host = t_end - (last_offset - end_offset + PACKET_SIZE - 1) * self.link.byte_ns
            t_dev = self._device_ns(p.timestamp_ms)
            self.clock.add(t_dev, t_host)
            angles = p.angles_deg()
            step_s = (
                ((p.end_angle_deg - p.start_angle_deg) % 360.0)
                / (POINTS_PER_PACKET - 1)
                / max(p.speed_dps, 1)
            )
            t_points = t_dev + np.round(np.arange(POINTS_PER_PACKET) * step_s * 1e9).astype(np.int64)
            new_rev = p.start_angle_deg < self._last_start
            self._last_start = p.start_angle_deg
            scan = self.assembler.add(
                new_rev, angles, p.distance_mm / 1000.0, p.intensity.astype(np.float32), t_points, t_host
            )
            if scan is not None:
                self.health.received += 1
                out.extend(self.stamper.push(scan))
        return out

    def close(self) -> None:
        self.link.close()
