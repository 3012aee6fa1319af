"""CRC-8 (poly 0x4D, LDROBOT) computed from a table, as the LD06/LD19/STL-27L firmware does."""

from __future__ import annotations


def _table(poly: int) -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


CRC8_TABLE = _table(0x4D)


def crc8(data: bytes) -> int:
    """CRC-8, polynomial 0x4D, initial value 0, no reflection, no final xor."""
    crc = 0
    for byte in data:
        crc = CRC8_TABLE[(crc ^ byte) & 0xFF]
    return crc
