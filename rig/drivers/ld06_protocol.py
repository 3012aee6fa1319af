"""LDROBOT LD06 / LD19 / STL-27L serial protocol: 47-byte measurement packets.

Written by hand: no maintained Python package parses these packets (the vendor ships a C++ ROS
driver only), and the format is small. Layout (little-endian)::

    0      header 0x54
    1      ver_len 0x2C (packet type 1, 12 points)
    2..3   speed, degrees per second
    4..5   start angle, 0.01 degree
    6..41  12 x (distance u16 mm, intensity u8)
    42..43 end angle, 0.01 degree
    44..45 timestamp, ms (wraps at 30000)
    46     CRC-8 (poly 0x4D) of bytes 0..45
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from rig.drivers.base import ParseError
from rig.drivers.crc import crc8

HEADER = 0x54
VER_LEN = 0x2C
PACKET_SIZE = 47
POINTS_PER_PACKET = 12
TIMESTAMP_WRAP_MS = 30000
#: Baud rates of the models (8N1: 10 bits on the wire per byte).
BAUD = {"ld06": 230400, "ld19": 230400, "stl27l": 921600}

_HEAD = struct.Struct("<BBHH")
_TAIL = struct.Struct("<HHB")
_POINT = np.dtype([("distance", "<u2"), ("intensity", "u1")])


@dataclass(frozen=True)
class LdPacket:
    """One decoded packet.

    Attributes:
        speed_dps: rotation speed, degrees/s.
        start_angle_deg, end_angle_deg: angle of the first and last point, degrees in [0, 360).
        distance_mm: ``(12,)`` uint16 (0 = no return).
        intensity: ``(12,)`` uint8.
        timestamp_ms: device time in ms, wrapping at 30000.
    """

    speed_dps: int
    start_angle_deg: float
    end_angle_deg: float
    distance_mm: np.ndarray
    intensity: np.ndarray
    timestamp_ms: int

    def angles_deg(self) -> np.ndarray:
        """``(12,)`` angle of each point, linearly spaced from start to end (across 360 → 0)."""
        span = (self.end_angle_deg - self.start_angle_deg) % 360.0
        return (self.start_angle_deg + span * np.arange(POINTS_PER_PACKET) / (POINTS_PER_PACKET - 1)) % 360.0


def parse_packet(data: bytes) -> LdPacket:
    """Decode exactly one 47-byte packet; raises :class:`ParseError` on bad length, header or CRC."""
    if len(data) != PACKET_SIZE:
        raise ParseError(f"LD06 packet must be {PACKET_SIZE} bytes, got {len(data)}")
    if data[0] != HEADER or data[1] != VER_LEN:
        raise ParseError(f"LD06 packet header must be 54 2c, got {data[0]:02x} {data[1]:02x}")
    if crc8(data[:46]) != data[46]:
        raise ParseError("LD06 packet CRC mismatch")
    _, _, speed, start = _HEAD.unpack_from(data, 0)
    points = np.frombuffer(data, dtype=_POINT, count=POINTS_PER_PACKET, offset=6)
    end, stamp, _ = _TAIL.unpack_from(data, 42)
    if start >= 36000 or end >= 36000:
        raise ParseError(f"LD06 angle out of range: start {start}, end {end} (0.01 degree units)")
    return LdPacket(
        speed, start / 100.0, end / 100.0, points["distance"].copy(), points["intensity"].copy(), stamp
    )


def encode_packet(
    speed_dps: int,
    start_angle_deg: float,
    end_angle_deg: float,
    distance_mm: np.ndarray,
    intensity: np.ndarray,
    timestamp_ms: int,
) -> bytes:
    """The 47 bytes of a packet (what the sensor sends; used by the mock device)."""
    points = np.zeros(POINTS_PER_PACKET, dtype=_POINT)
    points["distance"] = np.clip(np.asarray(distance_mm), 0, 65535)
    points["intensity"] = np.clip(np.asarray(intensity), 0, 255)
    body = (
        _HEAD.pack(HEADER, VER_LEN, int(speed_dps), round(start_angle_deg * 100) % 36000)
        + points.tobytes()
        + struct.pack("<HH", round(end_angle_deg * 100) % 36000, int(timestamp_ms) % TIMESTAMP_WRAP_MS)
    )
    return body + bytes([crc8(body)])


class LdStreamParser:
    """Finds packets in a byte stream, resynchronising on the header after corrupted bytes.

    Every call consumes at least one byte per loop step, so no input makes it spin.
    Counters: ``packets`` decoded, ``crc_errors`` (header found, CRC wrong), ``skipped_bytes``.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._consumed = 0  # stream offset of _buf[0]
        self.packets = 0
        self.crc_errors = 0
        self.skipped_bytes = 0

    def feed(self, data: bytes) -> list[tuple[int, LdPacket]]:
        """Append ``data``; return ``(stream offset of the packet's last byte, packet)`` pairs."""
        self._buf += data
        out: list[tuple[int, LdPacket]] = []
        pos = 0
        while True:
            start = self._buf.find(bytes((HEADER, VER_LEN)), pos)
            if start < 0:
                keep = 1 if self._buf[-1:] == bytes((HEADER,)) else 0
                self.skipped_bytes += len(self._buf) - pos - keep
                pos = len(self._buf) - keep
                break
            self.skipped_bytes += start - pos
            if len(self._buf) - start < PACKET_SIZE:
                pos = start
                break
            try:
                packet = parse_packet(bytes(self._buf[start : start + PACKET_SIZE]))
            except ParseError:
                self.crc_errors += 1
                pos = start + 1
                continue
            self.packets += 1
            out.append((self._consumed + start + PACKET_SIZE - 1, packet))
            pos = start + PACKET_SIZE
        del self._buf[:pos]
        self._consumed += pos
        return out

    @property
    def offset(self) -> int:
        """Stream offset just past the last byte fed."""
        return self._consumed + len(self._buf)
