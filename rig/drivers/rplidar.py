"""Slamtec RPLIDAR driver (pyserial): health/info, standard scan, host time from arrival."""

from __future__ import annotations

import itertools
import time
from typing import Any

import numpy as np

from rig.drivers import rplidar_protocol as rp
from rig.drivers.base import DeviceError, Driver, Message, ParseError
from rig.drivers.scan2d import RevolutionAssembler
from rig.drivers.serial_link import SerialLink

BAUD = {"a1": 115200, "a2": 115200, "a3": 256000, "c1": 460800, "s2": 1000000}


class RplidarDriver(Driver):
    """An RPLIDAR in standard scan mode. On every (re)connect: STOP, GET_HEALTH, GET_INFO, SCAN.

    The sensor has no clock in standard mode: scans carry ``t_device = None`` and ``t_host`` per node
    from arrival time minus serial transfer time.
    """

    kind = "rplidar"

    def __init__(self, name: str, port: str, model: str = "a1", baud: int | None = None) -> None:
        super().__init__(name)
        if model not in BAUD and baud is None:
            raise ValueError(
                f"unknown RPLIDAR model {model!r}; expected one of {sorted(BAUD)} or a baud rate"
            )
        self.port = port
        self.link = SerialLink(port, baud or BAUD[model], self.health)
        self.link.on_connect = self._handshake
        self.info: rp.DeviceInfo | None = None
        self.device_health: rp.DeviceHealth | None = None
        self.parser = rp.NodeStreamParser()
        self.assembler = RevolutionAssembler(name, device_clock=False)

    def _ask(self, cmd: int, expected: tuple[int, int, int]) -> bytes:
        self.link.write(rp.request(cmd))
        head = self.link.read_exact(rp.DESCRIPTOR_SIZE, 1.0)
        try:
            descriptor = rp.parse_descriptor(head)
        except ParseError as exc:
            raise DeviceError(f"RPLIDAR on {self.port} did not answer command {cmd:#04x}: {exc}") from exc
        if descriptor.as_tuple() != expected:
            raise DeviceError(f"RPLIDAR on {self.port}: unexpected descriptor {descriptor} for {cmd:#04x}")
        return self.link.read_exact(descriptor.length, 1.0) if descriptor.mode == rp.MODE_SINGLE else b""

    def _handshake(self) -> None:
        self.link.write(rp.request(rp.CMD_STOP))
        time.sleep(0.01)  # the protocol asks for >= 1 ms before the next request
        self.link.reset_input()
        try:
            self.device_health = rp.parse_health(self._ask(rp.CMD_GET_HEALTH, rp.HEALTH_DESCRIPTOR))
            self.info = rp.parse_info(self._ask(rp.CMD_GET_INFO, rp.INFO_DESCRIPTOR))
        except ParseError as exc:
            raise DeviceError(f"RPLIDAR on {self.port}: {exc}") from exc
        if self.device_health.status == "error":
            raise DeviceError(
                f"RPLIDAR on {self.port} reports error code {self.device_health.error_code:#06x}"
            )
        self._ask(rp.CMD_SCAN, rp.SCAN_DESCRIPTOR)
        self.parser = rp.NodeStreamParser()
        self.assembler.discard()

    def open(self) -> None:
        self.link.open()

    def stop(self) -> None:
        if self.link.connected:
            self.link.write(rp.request(rp.CMD_STOP))

    def device_id(self) -> str:
        return self.info.serial if self.info is not None else self.port

    def describe(self) -> dict[str, Any]:
        return {
            "port": self.port,
            "info": None if self.info is None else vars(self.info),
            "health": None if self.device_health is None else vars(self.device_health),
        }

    def read(self, timeout_s: float = 0.1) -> list[Message]:
        was_connected = self.link.connected
        data, t_end = self.link.read(timeout_s)
        if was_connected and not self.link.connected:
            self.assembler.discard()
            self.health.dropped += 1
        if not data:
            return []
        errors_before = self.parser.check_errors
        nodes, ends = self.parser.feed(data)
        self.health.crc_errors += self.parser.check_errors - errors_before
        self.health.packets += len(ends)
        if not len(ends):
            return []
        t_nodes = t_end - ((self.parser.offset - 1 - ends) + rp.NODE_SIZE - 1) * self.link.byte_ns
        out: list[Message] = []
        starts = set(np.flatnonzero(nodes.start).tolist())
        bounds = sorted({0, *starts, len(ends)})
        for a, b in itertools.pairwise(bounds):
            scan = self.assembler.add(
                a in starts,
                nodes.angle_deg[a:b],
                nodes.distance_mm[a:b] / 1000.0,
                nodes.quality[a:b].astype(np.float32),
                t_nodes[a:b],
                int(t_nodes[a]),
            )
            if scan is not None:
                self.health.received += 1
                out.append(scan)
        return out

    def close(self) -> None:
        self.link.close()
