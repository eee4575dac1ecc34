"""The IEU's check sums, table-driven (issue 17): CRC-32C (Castagnoli, reflected, as
crccheck's ``Crc32C``) over a sample's count frames and CRC-8/AUTOSAR (as crccheck's
``Crc8Autosar``) over a reply. The same values as crccheck's, at a byte a table look-up
instead of a bit a loop (tests/test_ieu_crc.py checks them against crccheck)."""

from __future__ import annotations


def _table32(poly_reflected: int) -> tuple[int, ...]:
    out = []
    for b in range(256):
        c = b
        for _ in range(8):
            c = (c >> 1) ^ poly_reflected if c & 1 else c >> 1
        out.append(c)
    return tuple(out)


def _table8(poly: int) -> tuple[int, ...]:
    out = []
    for b in range(256):
        c = b
        for _ in range(8):
            c = ((c << 1) ^ poly) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        out.append(c)
    return tuple(out)


CRC32C_TABLE = _table32(0x82F63B78)  # 0x1EDC6F41 reflected
CRC8_AUTOSAR_TABLE = _table8(0x2F)


def crc32c(data: bytes) -> int:
    """CRC-32C: init and final xor 0xFFFFFFFF, reflected in and out."""
    c = 0xFFFFFFFF
    t = CRC32C_TABLE
    for b in data:
        c = t[(c ^ b) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


def crc8_autosar(data: bytes) -> int:
    """CRC-8/AUTOSAR: polynomial 0x2F, init and final xor 0xFF, not reflected."""
    c = 0xFF
    t = CRC8_AUTOSAR_TABLE
    for b in data:
        c = t[c ^ b]
    return c ^ 0xFF
