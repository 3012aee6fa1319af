"""RPLIDAR protocol: requests, descriptors, info/health, 5-byte nodes, fuzzing."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.drivers import rplidar_protocol as rp
from rig.drivers.base import ParseError


def test_requests_are_byte_exact() -> None:
    assert rp.request(rp.CMD_SCAN) == b"\xa5\x20"
    assert rp.request(rp.CMD_STOP) == b"\xa5\x25"
    # Express-scan style request with payload: checksum = xor of all previous bytes.
    assert rp.request(0x82, b"\x00\x00\x00\x00\x00") == b"\xa5\x82\x05\x00\x00\x00\x00\x00" + bytes(
        [0xA5 ^ 0x82 ^ 0x05]
    )


def test_descriptors_from_the_protocol_document() -> None:
    assert rp.parse_descriptor(b"\xa5\x5a\x05\x00\x00\x40\x81").as_tuple() == rp.SCAN_DESCRIPTOR
    assert rp.parse_descriptor(b"\xa5\x5a\x14\x00\x00\x00\x04").as_tuple() == rp.INFO_DESCRIPTOR
    assert rp.parse_descriptor(b"\xa5\x5a\x03\x00\x00\x00\x06").as_tuple() == rp.HEALTH_DESCRIPTOR
    assert rp.encode_descriptor(*rp.SCAN_DESCRIPTOR) == b"\xa5\x5a\x05\x00\x00\x40\x81"
    with pytest.raises(ParseError):
        rp.parse_descriptor(b"\xa5\x5b\x05\x00\x00\x40\x81")


def test_info_and_health() -> None:
    info = rp.parse_info(bytes([0x18, 0x1D, 0x01, 0x07]) + bytes(range(16)))
    assert info.model == 0x18 and info.firmware == (1, 29) and info.hardware == 7
    assert info.serial == bytes(range(16)).hex().upper()
    assert rp.encode_info(info) == bytes([0x18, 0x1D, 0x01, 0x07]) + bytes(range(16))
    health = rp.parse_health(b"\x01\x34\x12")
    assert health.status == "warning" and health.error_code == 0x1234
    with pytest.raises(ParseError):
        rp.parse_health(b"\x03\x00\x00")


def test_node_bytes_by_hand() -> None:
    # quality 15, start flag, angle 90.0 deg (q6 = 5760), distance 1234.25 mm (q2 = 4937)
    q6, q2 = 5760, 4937
    node = bytes([(15 << 2) | 0b01, ((q6 & 0x7F) << 1) | 1, q6 >> 7, q2 & 0xFF, q2 >> 8])
    nodes = rp.parse_nodes(node)
    assert nodes.start.tolist() == [True] and nodes.quality.tolist() == [15]
    assert nodes.angle_deg.tolist() == [90.0] and nodes.distance_mm.tolist() == [1234.25]
    assert rp.encode_nodes(np.array([1]), np.array([15]), np.array([90.0]), np.array([1234.25])) == node
    bad = bytes([node[0] | 0b10]) + node[1:]  # S and !S both set
    with pytest.raises(ParseError):
        rp.parse_nodes(bad)


def test_node_stream_resyncs_after_corruption() -> None:
    n = 50
    data = rp.encode_nodes(np.arange(n) == 0, np.full(n, 10), np.linspace(0, 359, n), np.full(n, 1500.0))
    parser = rp.NodeStreamParser()
    corrupted = data[:100] + b"\xff" + data[100:]
    nodes, ends = parser.feed(corrupted[:33])
    more, more_ends = parser.feed(corrupted[33:])
    total = len(nodes.angle_deg) + len(more.angle_deg)
    assert parser.check_errors >= 1 and total >= n - 2
    assert len(ends) + len(more_ends) == total


@given(st.binary(max_size=64))
def test_fuzz_fixed_size_parsers(data: bytes) -> None:
    decoded = 0
    for parse in (rp.parse_descriptor, rp.parse_info, rp.parse_health, rp.parse_nodes):
        try:
            parse(data)
            decoded += 1
        except ParseError:
            continue
    assert decoded <= 2  # no byte string has every size at once (7, 20, 3, 5k bytes) except b""


@given(st.lists(st.binary(max_size=80), max_size=8))
def test_fuzz_node_stream(chunks: list[bytes]) -> None:
    parser = rp.NodeStreamParser()
    for chunk in chunks:
        nodes, ends = parser.feed(chunk)
        assert len(nodes.angle_deg) == len(ends)
    assert len(parser._buf) < rp.NODE_SIZE


def test_large_random_node_stream_is_consumed_quickly() -> None:
    import time

    data = np.random.default_rng(1).integers(0, 256, 200_000, dtype=np.uint8).tobytes()
    parser = rp.NodeStreamParser()
    start = time.monotonic()
    for i in range(0, len(data), 4096):
        nodes, ends = parser.feed(data[i : i + 4096])
        assert len(nodes.angle_deg) == len(ends)
    assert time.monotonic() - start < 5.0 and len(parser._buf) < rp.NODE_SIZE
