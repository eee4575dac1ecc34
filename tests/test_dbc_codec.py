"""config.dbc's struct codecs give cantools' bytes and values for every message they take."""

from __future__ import annotations

import numpy as np
import pytest

from config.dbc import Codecs, load_dbc, struct_codec

DB = load_dbc()
FAST = [m for m in DB.messages if struct_codec(m) is not None]


def test_the_count_frames_take_the_fast_path_and_bit_fields_do_not() -> None:
    names = {m.name for m in FAST}
    assert {"IEU_GYRO", "IEU_ACCEL_A", "IEU_ACCEL_B", "IEU_TIMER", "IEU_CHECK"} <= names
    assert "IEU_STATUS" not in names  # State and ErrorCode are 4-bit fields


@pytest.mark.parametrize("name", [m.name for m in FAST])
def test_struct_codec_matches_cantools(name: str) -> None:
    msg = DB.get_message_by_name(name)
    codec = Codecs(DB)
    rng = np.random.default_rng(sum(map(ord, name)))
    for _ in range(200):
        values = {}
        for s in msg.signals:
            lo = -(1 << (s.length - 1)) if s.is_signed else 0
            hi = (1 << (s.length - 1)) - 1 if s.is_signed else (1 << s.length) - 1
            values[s.name] = int(rng.integers(lo, hi, endpoint=True))
        assert codec.encode(name, values) == bytes(msg.encode(values, strict=False))
        raw = rng.integers(0, 256, msg.length, dtype=np.uint8).tobytes()
        want = {k: int(v) for k, v in msg.decode(raw, decode_choices=False).items()}
        assert codec.decode(name, raw) == want


def test_a_value_outside_its_width_falls_back_to_cantools() -> None:
    codec = Codecs(DB)
    msg = DB.get_message_by_name("IEU_GYRO")
    values = {"Seq": 1, "Gyro1": 40000, "Gyro2": 0, "Gyro3": -1}
    try:
        want: bytes | None = bytes(msg.encode(values, strict=False))
    except Exception:  # noqa: BLE001  # whatever cantools does, the codec must do the same
        want = None
    if want is None:
        with pytest.raises(Exception):  # noqa: B017
            codec.encode("IEU_GYRO", values)
    else:
        assert codec.encode("IEU_GYRO", values) == want
