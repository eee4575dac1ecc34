"""What a client reads from a links directory: ``session.json`` and ``links.json`` are
parsed strictly; anything else is refused with one line naming the file (hypothesis over
random text and JSON), and ``served`` reports it as no served rack."""

from __future__ import annotations

import json
from dataclasses import asdict

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from station.hil import link_map, session
from station.hil.link_map import BadLinkMap, LinkEntry
from station.hil.profile import NoServedRack, served
from station.hil.session import BadSession, Session

FAST = settings(max_examples=80, deadline=None, derandomize=True)
GOOD = Session("abc123", "isu", 7, 20.0, "0123456789abcdef", 1234.5, 4321)
ENTRIES = [LinkEntry("table", "serial", "/tmp/rack/table"),
           LinkEntry("ieu", "can", "socketcand://127.0.0.1:29536/ieu")]
json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner,
                                                                max_size=8),
    max_leaves=8)


def test_round_trips():
    assert session.parse(json.dumps(asdict(GOOD))) == GOOD
    assert link_map.parse(json.dumps([asdict(e) for e in ENTRIES])) == ENTRIES


@FAST
@given(st.one_of(st.text(max_size=200), json_values.map(json.dumps)))
def test_session_refuses_anything_else(text):
    try:
        s = session.parse(text)
    except BadSession as e:
        assert str(e).startswith("session.json: ") and "\n" not in str(e)
        return
    assert isinstance(s.seed, int) and s.speed > 0 and s.pid > 0


@FAST
@given(st.sampled_from(sorted(asdict(GOOD))), json_values)
def test_session_field_of_the_wrong_kind_is_named(field, value):
    data = asdict(GOOD) | {field: value}
    try:
        s = session.parse(json.dumps(data))
    except BadSession as e:
        assert field in str(e) or "positive" in str(e) or "JSON" in str(e)
        return
    assert getattr(s, field) == value  # a value of the right kind was drawn


@FAST
@given(st.one_of(st.text(max_size=200), json_values.map(json.dumps)))
def test_link_map_refuses_anything_else(text):
    try:
        entries = link_map.parse(text)
    except BadLinkMap as e:
        assert str(e).startswith("links.json: ") and "\n" not in str(e)
        return
    assert all(e.kind in ("serial", "can") for e in entries)


def test_can_addresses_need_host_and_port():
    assert link_map.can_config("socketcand://127.0.0.1:29536/ieu")["port"] == 29536
    for bad in ("socketcand://127.0.0.1/ieu", "socketcand://:80/ieu",
                "socketcand://127.0.0.1:99999/ieu", "socketcand://h:x/ieu"):
        with pytest.raises(BadLinkMap, match="needs a host and a port"):
            link_map.can_config(bad)


@pytest.mark.parametrize("which, text", [("session.json", "{"), ("session.json", "[]"),
                                         ("links.json", '[{"instrument": 1}]'),
                                         ("links.json", "\xff")])
def test_served_reports_a_malformed_directory_as_no_rack(tmp_path, which, text):
    (tmp_path / "session.json").write_text(json.dumps(asdict(GOOD)))
    (tmp_path / "links.json").write_text(json.dumps([asdict(e) for e in ENTRIES]))
    assert served(tmp_path).serial == {"table": "/tmp/rack/table"}
    (tmp_path / which).write_text(text)
    with pytest.raises(NoServedRack, match=rf"no served rack under .*{which}"):
        served(tmp_path)
