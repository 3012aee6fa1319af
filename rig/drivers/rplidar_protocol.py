"""Slamtec RPLIDAR (A-series, C1) serial protocol: requests, response descriptors, standard scan.

Written by hand: the Python packages for RPLIDAR (``rplidar``, ``rplidar-roboticia``) are
unmaintained, open the port themselves and cannot be fed bytes, so they cannot run against a
mock or be fuzzed. Layout (little-endian), from the protocol document:

- request: ``A5 CMD`` or ``A5 CMD SIZE PAYLOAD CHECKSUM`` (checksum = xor of all bytes before it).
- response descriptor (7 bytes): ``A5 5A``, 30-bit length + 2-bit send mode, data type.
- standard scan node (5 bytes): ``quality<<2 | !S<<1 | S``, ``angle_q6[6:0]<<1 | C`` (C = 1),
  ``angle_q6[14:7]``, ``distance_q2`` u16 (mm x 4). Angle in degrees = angle_q6 / 64.
- GET_INFO payload (20 bytes): model, firmware minor, firmware major, hardware, 16-byte serial.
- GET_HEALTH payload (3 bytes): status (0 good, 1 warning, 2 error), error code u16.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from rig.drivers.base import ParseError

SYNC1, SYNC2 = 0xA5, 0x5A
CMD_STOP, CMD_RESET, CMD_SCAN, CMD_GET_INFO, CMD_GET_HEALTH = 0x25, 0x40, 0x20, 0x50, 0x52
DESCRIPTOR_SIZE = 7
NODE_SIZE = 5
MODE_SINGLE, MODE_MULTI = 0, 1
#: (length, send mode, data type) of the answers this module decodes.
SCAN_DESCRIPTOR = (5, MODE_MULTI, 0x81)
INFO_DESCRIPTOR = (20, MODE_SINGLE, 0x04)
HEALTH_DESCRIPTOR = (3, MODE_SINGLE, 0x06)
HEALTH_STATUS = {0: "good", 1: "warning", 2: "error"}


def request(cmd: int, payload: bytes = b"") -> bytes:
    """Bytes of a request packet."""
    if not payload:
        return bytes((SYNC1, cmd))
    body = bytes((SYNC1, cmd, len(payload))) + payload
    checksum = 0
    for b in body:
        checksum ^= b
    return body + bytes((checksum,))


@dataclass(frozen=True)
class Descriptor:
    length: int
    mode: int
    data_type: int

    def as_tuple(self) -> tuple[int, int, int]:
        return (self.length, self.mode, self.data_type)


def parse_descriptor(data: bytes) -> Descriptor:
    if len(data) != DESCRIPTOR_SIZE:
        raise ParseError(f"RPLIDAR descriptor must be {DESCRIPTOR_SIZE} bytes, got {len(data)}")
    if data[0] != SYNC1 or data[1] != SYNC2:
        raise ParseError(f"RPLIDAR descriptor must start a5 5a, got {data[0]:02x} {data[1]:02x}")
    word = struct.unpack_from("<I", data, 2)[0]
    return Descriptor(word & 0x3FFFFFFF, word >> 30, data[6])


def encode_descriptor(length: int, mode: int, data_type: int) -> bytes:
    return (
        bytes((SYNC1, SYNC2)) + struct.pack("<I", (length & 0x3FFFFFFF) | (mode << 30)) + bytes((data_type,))
    )


@dataclass(frozen=True)
class DeviceInfo:
    model: int
    firmware: tuple[int, int]
    hardware: int
    serial: str


def parse_info(data: bytes) -> DeviceInfo:
    if len(data) != INFO_DESCRIPTOR[0]:
        raise ParseError(f"RPLIDAR info must be {INFO_DESCRIPTOR[0]} bytes, got {len(data)}")
    return DeviceInfo(data[0], (data[2], data[1]), data[3], data[4:20].hex().upper())


def encode_info(info: DeviceInfo) -> bytes:
    serial = bytes.fromhex(info.serial)
    return bytes((info.model, info.firmware[1], info.firmware[0], info.hardware)) + serial


@dataclass(frozen=True)
class DeviceHealth:
    status: str
    error_code: int


def parse_health(data: bytes) -> DeviceHealth:
    if len(data) != HEALTH_DESCRIPTOR[0]:
        raise ParseError(f"RPLIDAR health must be {HEALTH_DESCRIPTOR[0]} bytes, got {len(data)}")
    if data[0] not in HEALTH_STATUS:
        raise ParseError(f"RPLIDAR health status {data[0]} is not 0, 1 or 2")
    return DeviceHealth(HEALTH_STATUS[data[0]], struct.unpack_from("<H", data, 1)[0])


def encode_health(health: DeviceHealth) -> bytes:
    code = {v: k for k, v in HEALTH_STATUS.items()}[health.status]
    return bytes((code,)) + struct.pack("<H", health.error_code)


@dataclass(frozen=True)
class Nodes:
    """Decoded scan nodes, each ``(N,)``: new-revolution flag, quality (0..63), angle, distance."""

    start: np.ndarray
    quality: np.ndarray
    angle_deg: np.ndarray
    distance_mm: np.ndarray


def node_valid(data: bytes | np.ndarray) -> np.ndarray:
    """``(N,)`` bool: S and !S differ and the check bit is set, for ``(N*5,)`` node bytes."""
    raw = np.frombuffer(bytes(data), dtype=np.uint8).reshape(-1, NODE_SIZE)
    s, not_s = raw[:, 0] & 1, (raw[:, 0] >> 1) & 1
    return (s != not_s) & ((raw[:, 1] & 1) == 1)


def parse_nodes(data: bytes) -> Nodes:
    """Decode ``N`` consecutive 5-byte nodes; raises :class:`ParseError` if any fails its checks."""
    if len(data) % NODE_SIZE:
        raise ParseError(f"RPLIDAR node data must be a multiple of {NODE_SIZE} bytes, got {len(data)}")
    if not node_valid(data).all():
        raise ParseError("RPLIDAR node check bits (S, !S, C) are wrong")
    raw = np.frombuffer(data, dtype=np.uint8).reshape(-1, NODE_SIZE).astype(np.uint32)
    angle_q6 = (raw[:, 1] >> 1) | (raw[:, 2] << 7)
    return Nodes(
        start=(raw[:, 0] & 1).astype(bool),
        quality=(raw[:, 0] >> 2).astype(np.uint8),
        angle_deg=angle_q6 / 64.0,
        distance_mm=(raw[:, 3] | (raw[:, 4] << 8)) / 4.0,
    )


def encode_nodes(
    start: np.ndarray, quality: np.ndarray, angle_deg: np.ndarray, distance_mm: np.ndarray
) -> bytes:
    """Bytes of ``N`` standard scan nodes (used by the mock device)."""
    start = np.asarray(start, dtype=np.uint32)
    angle_q6 = np.clip(np.round(np.asarray(angle_deg) * 64.0), 0, 0x7FFF).astype(np.uint32)
    dist_q2 = np.clip(np.round(np.asarray(distance_mm) * 4.0), 0, 0xFFFF).astype(np.uint32)
    raw = np.empty((len(start), NODE_SIZE), dtype=np.uint8)
    raw[:, 0] = (np.clip(np.asarray(quality), 0, 63).astype(np.uint32) << 2) | ((1 - start) << 1) | start
    raw[:, 1] = ((angle_q6 & 0x7F) << 1) | 1
    raw[:, 2] = angle_q6 >> 7
    raw[:, 3] = dist_q2 & 0xFF
    raw[:, 4] = dist_q2 >> 8
    return raw.tobytes()


class NodeStreamParser:
    """Cuts a scan-mode byte stream into nodes; a node failing its check bits is counted and the
    parser slides one byte to resynchronise. Each step consumes at least one byte."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._consumed = 0
        self.nodes = 0
        self.check_errors = 0

    def feed(self, data: bytes) -> tuple[Nodes, np.ndarray]:
        """Append ``data``; return the complete valid nodes and each one's last-byte stream offset."""
        self._buf += data
        good: list[bytes] = []
        ends: list[int] = []
        pos = 0
        n = len(self._buf)
        while n - pos >= NODE_SIZE:
            count = (n - pos) // NODE_SIZE
            block = bytes(self._buf[pos : pos + count * NODE_SIZE])
            valid = node_valid(block)
            first_bad = count if valid.all() else int(np.argmin(valid))
            if first_bad:
                good.append(block[: first_bad * NODE_SIZE])
                ends.extend(self._consumed + pos + NODE_SIZE * np.arange(1, first_bad + 1) - 1)
                pos += first_bad * NODE_SIZE
            if first_bad < count:
                self.check_errors += 1
                pos += 1
        del self._buf[:pos]
        self._consumed += pos
        data_ok = b"".join(good)
        self.nodes += len(data_ok) // NODE_SIZE
        return parse_nodes(data_ok), np.asarray(ends, dtype=np.int64)

    @property
    def offset(self) -> int:
        """Stream offset just past the last byte fed."""
        return self._consumed + len(self._buf)
