"""The IEU driver's table-driven check sums equal crccheck's (issue 17)."""

from __future__ import annotations

import random

from crccheck.crc import Crc8Autosar, Crc32C

from station.drivers.isu.crc import crc8_autosar, crc32c


def test_crc32c_and_crc8_autosar_equal_crccheck_on_random_data() -> None:
    rng = random.Random(17)
    for n in [0, 1, 2, 7, 8, 32, 40, 257]:
        for _ in range(20):
            data = bytes(rng.randrange(256) for _ in range(n))
            assert crc32c(data) == Crc32C.calc(data)
            assert crc8_autosar(data) == Crc8Autosar.calc(data)


def test_check_values_of_the_catalogue() -> None:
    """The catalogue's check value of each CRC over b"123456789"."""
    assert crc32c(b"123456789") == 0xE3069283
    assert crc8_autosar(b"123456789") == 0xDF
