"""Station configuration: malformed files are refused naming the field; `station check`."""

from __future__ import annotations

import copy
import json

import pytest
from typer.testing import CliRunner

import station.config.isu as station_config
from laboratory.cli import app
from station.config.isu import SERIAL_INSTRUMENTS, ConfigError, default_dict, load_config

ALL_INSTRUMENTS = [*SERIAL_INSTRUMENTS, "ieu"]


def write(tmp_path, text: str, name: str = "station.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def gyros_with(k: int, field: str, value) -> dict:
    """Overrides replacing the gyro list (TOML arrays replace, they do not merge)."""
    gyros = copy.deepcopy(default_dict()["isu"]["gyros"])
    gyros[k][field] = value
    return {"isu": {"gyros": gyros}}


# ----------------------------------------------------------------------------- load_config


def test_default_and_a_partial_user_file_load(tmp_path):
    cfg = load_config()
    assert cfg.links.serial["counter3"] == "sim://counter3"
    p = write(tmp_path, "seed = 7\n[table]\nmax_rate_deg_s = 18.0\n")
    user = load_config(p)
    assert (user.seed, user.table.max_rate_deg_s) == (7, 18.0)
    assert user.table.slew_rate_deg_s == cfg.table.slew_rate_deg_s  # merged over the default
    assert load_config(p, seed=3).seed == 3


@pytest.mark.parametrize(
    ("overrides", "path"),
    [
        # wrong type
        (gyros_with(0, "R_deg_hr", "abc"), "isu.gyros.0.R_deg_hr"),
        ({"site": {"latitude_deg": "north"}}, "site.latitude_deg"),
        ({"environment": {"vibration": {"tones": 2.5}}}, "environment.vibration.tones"),
        ({"table": {"trunnion_range_deg": [1.0]}}, "table.trunnion_range_deg.1"),
        ({"links": {"serial": "sim://table"}}, "links.serial"),
        # unknown field
        ({"table": {"slew_rate": 5.0}}, "table.slew_rate"),
        ({"colour": "blue"}, "colour"),
        (gyros_with(2, "bias", 1.0), "isu.gyros.2.bias"),
        ({"links": {"serial": {"counter7": "sim://counter7"}}}, "links.serial"),
        # out of range
        ({"site": {"latitude_deg": 100.0}}, "site.latitude_deg"),
        ({"seed": -1}, "seed"),
        ({"instruments": {"serial": {"latency_s": 2.0}}}, "instruments.serial.latency_s"),
        ({"instruments": {"autocollimator": {"fov_deg": 0}}}, "instruments.autocollimator.fov_deg"),
        (gyros_with(1, "drift_tau_s", 0.0), "isu.gyros.1.drift_tau_s"),
        ({"oscillator": {"s2_divider": 0}}, "oscillator.s2_divider"),
        # not a number at all
        (gyros_with(0, "R_deg_hr", float("nan")), "isu.gyros.0.R_deg_hr"),
        (
            gyros_with(2, "scale_factor_arcsec_per_pulse", float("inf")),
            "isu.gyros.2.scale_factor_arcsec_per_pulse",
        ),
        ({"site": {"earth_rate_deg_per_hr": float("inf")}}, "site.earth_rate_deg_per_hr"),
    ],
)
def test_malformed_values_name_the_field(overrides, path):
    with pytest.raises(ConfigError) as e:
        load_config(overrides=overrides)
    msg = str(e.value)
    assert "\n" not in msg  # one line
    head, fields = msg.split(": ", 1)
    assert head == "invalid station configuration in the embedded default with overrides"
    assert fields.startswith(f"{path}: ") and "; " not in fields, msg  # that field alone


def test_unknown_instrument_link_is_named():
    with pytest.raises(ConfigError, match=r"links\.serial: .*unknown instrument counter7"):
        load_config(overrides={"links": {"serial": {"counter7": "sim://counter7"}}})


def test_missing_link_for_an_instrument_is_named(monkeypatch):
    # A user file merges over the default and cannot drop a link; a default that lacks one can.
    broken = default_dict()
    del broken["links"]["serial"]["counter3"]
    monkeypatch.setattr(station_config, "default_dict", lambda: copy.deepcopy(broken))
    with pytest.raises(ConfigError, match=r"links\.serial: .*missing counter3"):
        load_config()


def test_every_bad_field_of_a_user_file_is_named_with_the_file(tmp_path):
    p = write(tmp_path, '[site]\nlatitude_deg = "north"\n[table]\nslew_rate = 5.0\n')
    with pytest.raises(ConfigError) as e:
        load_config(p)
    msg = str(e.value)
    assert msg.startswith(f"invalid station configuration in {p}: ") and "\n" not in msg
    assert ": table.slew_rate: unknown field (did you mean slew_rate_deg_s?); " in msg
    assert "; site.latitude_deg: Input should be a valid number (got 'north')" in msg


def test_nan_in_a_toml_file_is_refused(tmp_path):
    p = write(tmp_path, "[oscillator]\nfrequency_error = nan\n")
    with pytest.raises(ConfigError, match=r"oscillator\.frequency_error: "):
        load_config(p)


def test_bad_toml_names_the_file_and_line(tmp_path):
    p = write(tmp_path, "seed = 3\n[site\nlatitude_deg = 1.0\n")
    with pytest.raises(ConfigError) as e:
        load_config(p)
    assert str(p) in str(e.value) and "not valid TOML" in str(e.value)
    assert "line 2" in str(e.value)


def test_missing_file_is_named(tmp_path):
    p = tmp_path / "nowhere.toml"
    with pytest.raises(ConfigError, match="not found") as e:
        load_config(p)
    assert str(p) in str(e.value)


# ----------------------------------------------------------------------------- station check

runner = CliRunner()


def test_check_default_config_every_instrument_answers():
    r = runner.invoke(app, ["check"])
    assert r.exit_code == 0, r.output
    rows = {
        line.split("│")[1].strip(): line.split("│")[3].strip()
        for line in r.stdout.splitlines()
        if line.startswith("│") and line.split("│")[1].strip()
    }
    assert rows == dict.fromkeys(ALL_INSTRUMENTS, "yes")


def test_check_json_lists_every_instrument_ok():
    r = runner.invoke(app, ["check", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert isinstance(out, list)
    assert [o["instrument"] for o in out] == ALL_INSTRUMENTS
    for o in out:
        assert {"instrument", "link", "ok"} <= set(o)
        assert o["ok"] is True
    links = {o["instrument"]: o["link"] for o in out}
    assert links["counter3"] == "sim://counter3"
    assert links["ieu"] == "sim:ieu"


# a device path among simulated links is refused by the config (test_hil_profile.py);
# dead hardware links are named by the check there
@pytest.mark.parametrize("link", ["sim://nope"])
def test_check_names_an_instrument_on_a_dead_link(tmp_path, link):
    p = write(tmp_path, f'[links.serial]\ncounter3 = "{link}"\n')
    r = runner.invoke(app, ["check", "--config", str(p), "--json"])
    assert r.exit_code == 1, r.output
    out = {o["instrument"]: o for o in json.loads(r.stdout)}
    assert set(out) == set(ALL_INSTRUMENTS)
    assert out["counter3"]["ok"] is False
    assert out["counter3"]["link"] == link
    assert all(o["ok"] for n, o in out.items() if n != "counter3")
    assert "not answering: counter3" in r.stderr

    r = runner.invoke(app, ["check", "--config", str(p)])
    assert r.exit_code == 1
    assert "counter3" in r.stdout
    assert r.stderr.strip() == "not answering: counter3"


@pytest.mark.parametrize(
    ("text", "names"),
    [
        ('[site]\nlatitude_deg = "north"\n', "site.latitude_deg"),
        ("[instruments.ieu]\nmax_period_s = -1.0\n", "instruments.ieu.max_period_s"),
        ("[table]\nslew_rate = 5.0\n", "table.slew_rate"),
        ("[site\n", "not valid TOML"),
    ],
)
def test_check_malformed_config_exits_2_naming_the_field(tmp_path, text, names):
    p = write(tmp_path, text)
    r = runner.invoke(app, ["check", "--config", str(p)])
    assert r.exit_code == 2
    assert names in " ".join(r.output.split())  # the console wraps long lines


def test_check_missing_config_file_exits_2(tmp_path):
    p = tmp_path / "nowhere.toml"
    r = runner.invoke(app, ["check", "--config", str(p)])
    assert r.exit_code == 2
    assert "not found" in r.output
    assert str(p) in "".join(r.output.split())  # a long path may be folded by the console
