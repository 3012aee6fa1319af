"""Livox Mid-360 (SDK2 / HAP protocol) UDP data packets: point clouds and IMU.

Written by hand: Livox ships only the C++ SDK2 (no Python bindings on PyPI that run without the
device), and the data packet is a fixed header plus a flat array. Layout (little-endian)::

    0   version u8          1  length u16 (whole packet)   3  time_interval u16 (0.1 us)
    5   dot_num u16         7  udp_cnt u16                  9  frame_cnt u8
    10  data_type u8        11 time_type u8                 12 reserved[12]
    24  crc32 u32 (CRC-32 of bytes 28..end: timestamp + data)
    28  timestamp u64 ns    36 data

Data types: 0 IMU (gyro xyz rad/s, acc xyz g: 6 float32), 1 Cartesian high (x y z int32 mm,
reflectivity u8, tag u8), 2 Cartesian low (x y z int16 cm, reflectivity, tag). Default ports on
the host: points 56301, IMU 56401.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

from rig.drivers.base import ParseError

HEADER = struct.Struct("<BHHHHBBB12sIQ")
HEADER_SIZE = HEADER.size  # 36
DATA_IMU, DATA_CART_HIGH, DATA_CART_LOW = 0, 1, 2
POINT_PORT, IMU_PORT = 56301, 56401
GRAVITY = 9.80665

_DTYPES = {
    DATA_CART_HIGH: (np.dtype([("xyz", "<i4", (3,)), ("reflectivity", "u1"), ("tag", "u1")]), 1e-3),
    DATA_CART_LOW: (np.dtype([("xyz", "<i2", (3,)), ("reflectivity", "u1"), ("tag", "u1")]), 1e-2),
}
_IMU = struct.Struct("<6f")


@dataclass(frozen=True)
class LivoxPacket:
    """One decoded packet.

    Attributes:
        data_type: 0 IMU, 1 Cartesian high, 2 Cartesian low.
        timestamp_ns: device time of the first point (or of the IMU sample).
        time_interval_ns: time covered by the packet's points.
        udp_cnt, frame_cnt: sender counters (gaps in ``udp_cnt`` are lost packets).
        points: ``(N, 3)`` float64 metres (empty for IMU).
        reflectivity, tag: ``(N,)`` uint8.
        gyro: ``(3,)`` rad/s and ``acc``: ``(3,)`` m/s² (IMU packets only, else None).
    """

    data_type: int
    timestamp_ns: int
    time_interval_ns: int
    udp_cnt: int
    frame_cnt: int
    points: np.ndarray
    reflectivity: np.ndarray
    tag: np.ndarray
    gyro: np.ndarray | None = None
    acc: np.ndarray | None = None

    def point_offsets_ns(self) -> np.ndarray:
        """``(N,)`` int64 time of each point after ``timestamp_ns``, spread over the interval."""
        n = len(self.points)
        return (np.arange(n, dtype=np.int64) * self.time_interval_ns) // max(n, 1)


def parse_packet(data: bytes) -> LivoxPacket:
    """Decode one UDP datagram; raises :class:`ParseError` on any inconsistency."""
    if len(data) < HEADER_SIZE:
        raise ParseError(f"Livox packet shorter than its {HEADER_SIZE}-byte header: {len(data)} bytes")
    version, length, interval, dot_num, udp_cnt, frame_cnt, data_type, _, _, crc, stamp = HEADER.unpack_from(
        data, 0
    )
    if length != len(data):
        raise ParseError(f"Livox length field {length} != datagram size {len(data)}")
    if zlib.crc32(data[28:]) != crc:
        raise ParseError("Livox packet CRC-32 mismatch")
    body = len(data) - HEADER_SIZE
    empty = np.zeros(0, dtype=np.uint8)
    if data_type == DATA_IMU:
        if dot_num != 1 or body != _IMU.size:
            raise ParseError(f"Livox IMU packet must hold 1 sample of {_IMU.size} bytes")
        values = np.array(_IMU.unpack_from(data, HEADER_SIZE), dtype=np.float64)
        return LivoxPacket(
            data_type,
            stamp,
            interval * 100,
            udp_cnt,
            frame_cnt,
            np.zeros((0, 3)),
            empty,
            empty,
            gyro=values[:3],
            acc=values[3:] * GRAVITY,
        )
    if data_type not in _DTYPES:
        raise ParseError(f"Livox data type {data_type} is not 0 (IMU), 1 or 2 (Cartesian)")
    dtype, scale = _DTYPES[data_type]
    if body != dot_num * dtype.itemsize:
        raise ParseError(
            f"Livox packet of {dot_num} points needs {dot_num * dtype.itemsize} data bytes, has {body}"
        )
    del version  # every released firmware sends 0; accept others (no layout change is documented)
    pts = np.frombuffer(data, dtype=dtype, count=dot_num, offset=HEADER_SIZE)
    return LivoxPacket(
        data_type,
        stamp,
        interval * 100,
        udp_cnt,
        frame_cnt,
        pts["xyz"].astype(np.float64) * scale,
        pts["reflectivity"].copy(),
        pts["tag"].copy(),
    )


def _packet(
    data_type: int, dot_num: int, interval_ns: int, udp_cnt: int, frame_cnt: int, stamp: int, body: bytes
) -> bytes:
    tail = struct.pack("<Q", stamp) + body
    head = HEADER.pack(
        0,
        HEADER_SIZE + len(body),
        min(interval_ns // 100, 0xFFFF),
        dot_num,
        udp_cnt & 0xFFFF,
        frame_cnt & 0xFF,
        data_type,
        0,
        bytes(12),
        zlib.crc32(tail),
        stamp,
    )
    return head[:28] + tail


def encode_points(
    points_m: np.ndarray,
    reflectivity: np.ndarray,
    timestamp_ns: int,
    interval_ns: int,
    udp_cnt: int,
    frame_cnt: int,
    data_type: int = DATA_CART_HIGH,
) -> bytes:
    """A point packet of ``(N, 3)`` points (used by the mock sender)."""
    dtype, scale = _DTYPES[data_type]
    arr = np.zeros(len(points_m), dtype=dtype)
    info = np.iinfo(dtype["xyz"].base)
    arr["xyz"] = np.clip(np.round(np.asarray(points_m) / scale), info.min, info.max)
    arr["reflectivity"] = np.clip(np.asarray(reflectivity), 0, 255)
    return _packet(data_type, len(arr), interval_ns, udp_cnt, frame_cnt, timestamp_ns, arr.tobytes())


def encode_imu(gyro: np.ndarray, acc_ms2: np.ndarray, timestamp_ns: int, udp_cnt: int) -> bytes:
    """An IMU packet (acceleration sent in g, as the sensor does)."""
    body = _IMU.pack(*np.asarray(gyro, float), *(np.asarray(acc_ms2, float) / GRAVITY))
    return _packet(DATA_IMU, 1, 0, udp_cnt, 0, timestamp_ns, body)
