"""LD06/LD19 packets: byte-exact decoding, CRC, stream resynchronisation, fuzzing."""

import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.drivers.base import ParseError
from rig.drivers.crc import CRC8_TABLE, crc8
from rig.drivers.ld06_protocol import LdStreamParser, encode_packet, parse_packet


def hand_packet() -> bytes:
    """A packet laid out field by field from the datasheet, CRC from the vendor's table."""
    body = bytes([0x54, 0x2C]) + struct.pack("<H", 3600) + struct.pack("<H", 35900)  # 359.00 deg
    for i in range(12):
        body += struct.pack("<HB", 1000 + i, 200 - i)
    body += struct.pack("<H", 1100) + struct.pack("<H", 29999)  # end 11.00 deg, stamp 29999 ms
    return body + bytes([crc8(body)])


def test_crc_table_matches_vendor_table_start() -> None:
    # First entries of the table in LDROBOT's SDK (poly 0x4D).
    assert CRC8_TABLE[:8] == (0x00, 0x4D, 0x9A, 0xD7, 0x79, 0x34, 0xE3, 0xAE)


def test_hand_built_packet_decodes_exactly() -> None:
    data = hand_packet()
    assert len(data) == 47
    p = parse_packet(data)
    assert p.speed_dps == 3600 and p.timestamp_ms == 29999
    assert p.start_angle_deg == 359.0 and p.end_angle_deg == 11.0
    np.testing.assert_array_equal(p.distance_mm, 1000 + np.arange(12))
    np.testing.assert_array_equal(p.intensity, 200 - np.arange(12))
    angles = p.angles_deg()  # 12 degrees across the 360 -> 0 wrap
    np.testing.assert_allclose(angles[[0, 1, 11]], [359.0, 0.0909090909, 11.0], atol=1e-6)
    assert encode_packet(3600, 359.0, 11.0, 1000 + np.arange(12), 200 - np.arange(12), 29999) == data


@pytest.mark.parametrize("index", [0, 1, 5, 20, 46])
def test_any_flipped_byte_is_rejected(index: int) -> None:
    data = bytearray(hand_packet())
    data[index] ^= 0x10
    with pytest.raises(ParseError):
        parse_packet(bytes(data))


def test_stream_parser_counts_crc_errors_and_resyncs() -> None:
    good = hand_packet()
    bad = bytearray(good)
    bad[10] ^= 0xFF
    stream = b"\x00\x54\x99" + good + bytes(bad) + good[:20]
    parser = LdStreamParser()
    got = parser.feed(stream[:30]) + parser.feed(stream[30:])
    assert len(got) == 1 and parser.crc_errors == 1
    got = parser.feed(good[20:] + good)
    assert len(got) == 2 and parser.packets == 3
    assert got[-1][0] == parser.offset - 1  # offset of the last byte of the last packet


@given(st.binary(max_size=200))
def test_fuzz_parse_packet_raises_only_parse_error(data: bytes) -> None:
    try:
        packet = parse_packet(data)
    except ParseError:
        return
    assert len(data) == 47 and crc8(data[:46]) == data[46] and packet.distance_mm.shape == (12,)


@given(st.lists(st.binary(max_size=120), max_size=8), st.integers(0, 3))
def test_fuzz_stream_never_raises_and_finds_embedded_packets(chunks: list[bytes], copies: int) -> None:
    parser = LdStreamParser()
    found = 0
    for chunk in chunks:
        found += len(parser.feed(chunk))
    found += len(parser.feed(b"\x00" * 47 + hand_packet() * copies))
    assert found >= copies
    assert len(parser._buf) < 47 + 2 * 47  # bounded buffer


def test_large_random_stream_is_consumed_quickly() -> None:
    import time

    rng = np.random.default_rng(0)
    noise = rng.integers(0, 256, 300_000, dtype=np.uint8)
    noise[::50] = 0x54  # many false headers
    noise[1::50] = 0x2C
    parser = LdStreamParser()
    start = time.monotonic()
    for i in range(0, noise.size, 4096):
        parser.feed(noise[i : i + 4096].tobytes())
    assert time.monotonic() - start < 5.0
    assert parser.crc_errors >= 5000 and len(parser._buf) < 47
