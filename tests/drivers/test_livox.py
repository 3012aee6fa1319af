"""Livox Mid-360 SDK2 packets: byte-exact point and IMU packets, fuzzing."""

import struct
import zlib

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.drivers import livox_protocol as lp
from rig.drivers.base import ParseError


def hand_point_packet() -> bytes:
    """Two Cartesian-high points, header written field by field."""
    data = struct.pack("<iiiBB", 1000, -2000, 300, 77, 0) + struct.pack("<iiiBB", -5, 6, 7, 255, 1)
    stamp = struct.pack("<Q", 123_456_789_000)
    header = struct.pack("<BHHHHBBB", 0, 36 + len(data), 100, 2, 9, 3, 1, 0) + bytes(12)
    return header + struct.pack("<I", zlib.crc32(stamp + data)) + stamp + data


def test_hand_built_point_packet() -> None:
    data = hand_point_packet()
    assert len(data) == 36 + 28
    p = lp.parse_packet(data)
    assert p.data_type == 1 and p.udp_cnt == 9 and p.frame_cnt == 3
    assert p.timestamp_ns == 123_456_789_000 and p.time_interval_ns == 10_000
    np.testing.assert_allclose(p.points, [[1.0, -2.0, 0.3], [-0.005, 0.006, 0.007]])
    assert p.reflectivity.tolist() == [77, 255] and p.tag.tolist() == [0, 1]
    assert p.point_offsets_ns().tolist() == [0, 5000]
    again = lp.encode_points(p.points, p.reflectivity, p.timestamp_ns, 10_000, 9, 3)
    assert lp.parse_packet(again).points.tolist() == p.points.tolist()


def test_cartesian_low_and_imu() -> None:
    data = struct.pack("<hhhBB", 150, -20, 3, 10, 0)
    stamp = struct.pack("<Q", 5)
    header = struct.pack("<BHHHHBBB", 0, 36 + len(data), 0, 1, 0, 0, 2, 0) + bytes(12)
    p = lp.parse_packet(header + struct.pack("<I", zlib.crc32(stamp + data)) + stamp + data)
    np.testing.assert_allclose(p.points, [[1.5, -0.2, 0.03]])
    imu = lp.parse_packet(lp.encode_imu(np.array([0.1, 0.2, 0.3]), np.array([0.0, 0.0, 9.80665]), 42, 7))
    assert imu.data_type == 0 and imu.timestamp_ns == 42
    np.testing.assert_allclose(imu.gyro, [0.1, 0.2, 0.3], rtol=1e-6)
    np.testing.assert_allclose(imu.acc, [0.0, 0.0, 9.80665], rtol=1e-6)


@pytest.mark.parametrize("index", [1, 5, 30, 40, 60])
def test_corruption_is_rejected(index: int) -> None:
    data = bytearray(hand_point_packet())
    data[index] ^= 0x01
    with pytest.raises(ParseError):
        lp.parse_packet(bytes(data))


@given(st.binary(max_size=300))
def test_fuzz_random_bytes(data: bytes) -> None:
    try:
        packet = lp.parse_packet(data)
    except ParseError:
        return
    assert zlib.crc32(data[28:]) == struct.unpack_from("<I", data, 24)[0] and packet.points.shape[1] == 3


@given(st.binary(min_size=0, max_size=100), st.integers(0, 3))
def test_fuzz_valid_crc_random_body(body: bytes, data_type: int) -> None:
    # A correct length and CRC around random data: only the layout checks stand in the way.
    stamp = struct.pack("<Q", 1)
    head = struct.pack("<BHHHHBBB", 0, 36 + len(body), 0, len(body) // 14, 0, 0, data_type, 0) + bytes(12)
    try:
        packet = lp.parse_packet(head + struct.pack("<I", zlib.crc32(stamp + body)) + stamp + body)
    except ParseError:
        return
    assert packet.data_type == data_type and len(packet.points) == len(packet.reflectivity)
