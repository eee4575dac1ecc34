"""The real-hardware link profile of docs/hil.md: valid config, and it leads to hardware.

socketcan and the serial devices do not exist on these machines: the profile is checked
for validity and for what the station does with it (no simulated rack; a clean failure
naming the first link it cannot open), not run against hardware.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from laboratory.check import check_all
from laboratory.connect import connect
from laboratory.isu.lab import LAB, simulated
from station.config.isu import ConfigError, load_config
from station.errors import DriverError

DOC = Path(__file__).resolve().parents[1] / "docs" / "hil.md"


@pytest.fixture
def lab_toml(tmp_path) -> Path:
    blocks = re.findall(r"```toml\n(.*?)```", DOC.read_text(), re.S)
    (profile,) = [b for b in blocks if "[links.serial]" in b]
    path = tmp_path / "lab.toml"
    path.write_text(profile)
    return path


def test_documented_profile_is_a_valid_config_for_hardware(lab_toml):
    cfg = load_config(lab_toml)
    assert cfg.links.can.interface == "socketcan" and cfg.links.can.channel == "can0"
    assert all(u.startswith("/dev/") for u in cfg.links.serial.values())
    assert not simulated(cfg)


def test_profile_missing_an_instrument_is_refused(lab_toml, tmp_path):
    """Merged over the default, a left-out instrument would get its sim:// link: refused."""
    text = lab_toml.read_text().replace('counter3 = "/dev/ttyUSB4"\n', "")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=r"links: .*counter3.* mixed with hardware links"):
        load_config(bad)


def test_hardware_profile_fails_cleanly_naming_the_link(lab_toml):
    cfg = load_config(lab_toml)
    with pytest.raises(DriverError) as e:
        connect(LAB, cfg)
    assert "/dev/ttyUSB0" in str(e.value) and "table" in str(e.value)
    results = check_all(LAB, cfg, timeout=0.5)
    assert not any(r.ok for r in results)
    ieu = next(r for r in results if r.instrument == "ieu")
    assert "socketcan:can0" in ieu.link and "cannot open CAN link" in ieu.identity


def test_unknown_can_interface_is_a_config_error(lab_toml, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(lab_toml.read_text().replace('"socketcan"', '"sockcan"'))
    with pytest.raises(ConfigError, match=r"links\.can\.interface"):
        load_config(bad)
