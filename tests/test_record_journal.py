"""The journal is only ever appended to; a torn last line is set aside, any other bad line
refuses the resume with file:line and leaves the file byte for byte; record files are
written atomically and only under plain names."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs

from laboratory.record import sheet_path, write_json, write_sheets
from procedures.journal import Journal, JournalError, dumps, scan
from procedures.runner import Run
from station.clock import VirtualClock
from station.files import atomic_path


def sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def records(n_steps: int = 3) -> list[dict]:
    """A small journal in the day's shapes: start note, steps, a sheet, its block."""
    out: list[dict] = [{"kind": "note", "event": "start", "seed": 1}]
    out += [{"kind": "step", "chart": "I-1", "step": str(i), "text": "t", "t_sim": float(i),
             "reading": {"x": i}, "wall": "w"} for i in range(1, n_steps + 1)]
    out.append({"kind": "sheet", "name": "check_I-1", "data": {"chart": "I-1", "title": "T",
                                                               "steps": []}, "wall": "w"})
    out.append({"kind": "block", "key": "I-1", "data": None, "sheets": ["check_I-1"]})
    return out


def write(path: Path, recs: list[dict]) -> bytes:
    j = Journal(path)
    for r in recs:
        j.append(r)
    j.close()
    return path.read_bytes()


def test_new_journal_refuses_an_existing_one_and_resume_only_appends(tmp_path):
    path = tmp_path / "journal.jsonl"
    before = write(path, records())
    with pytest.raises(JournalError, match="already holds a journal"):
        Journal(path)
    assert path.read_bytes() == before
    j = Journal(path, resume=True)
    assert j.records == json.loads("[" + before.decode().strip().replace("\n", ",") + "]")
    j.append({"kind": "note", "event": "end"})
    j.close()
    after = path.read_bytes()
    assert after.startswith(before) and after[len(before):] == b'{"event":"end","kind":"note"}\n'
    assert scan(path).complete


@pytest.mark.parametrize("tail", [b'{"kind":"step","chart":"I-1","st',  # cut mid-record
                                  b'{"kind":"note","event":"x"}',  # whole, newline missing
                                  b'{"kind":"st\xff\xfe\n'])  # a last line that does not parse
def test_torn_last_line_is_set_aside_and_cut_exactly(tmp_path, tail):
    path = tmp_path / "journal.jsonl"
    whole = write(path, records())
    with open(path, "ab") as f:
        f.write(tail)
    (tmp_path / "journal.jsonl.torn-1").write_bytes(b"an earlier one")
    j = Journal(path, resume=True)
    j.close()
    assert path.read_bytes() == whole  # exactly the torn bytes were cut
    assert j.torn_to == tmp_path / "journal.jsonl.torn-2"  # a free side-file name
    assert j.torn_to.read_bytes() == tail
    assert (tmp_path / "journal.jsonl.torn-1").read_bytes() == b"an earlier one"
    assert len(j.records) == len(records())


@pytest.mark.parametrize(("bad", "why"), [
    (b"garbage", "not a JSON record"),
    (b"42", "not a record"),
    (b'["kind", "step"]', "not a record"),
    (b'{"foo": 1}', "unknown record kind"),
    (b'{"kind": "stp", "chart": "I-1"}', "unknown record kind"),
    (b'{"kind": "step", "chart": "I-1", "step": "1", "t_sim": NaN}', "finite t_sim"),
    (b'{"kind": "sheet", "name": "../../X", "data": {}}', "outside the run directory"),
    (b'{"kind": "sheet", "name": ".hidden", "data": {}}', "not a plain file name"),
    (b'{"kind": "block", "key": "I-2", "data": 1, "sheets": ["../../X"]}', "outside the run"),
    (b'{"kind": "block", "key": "I-2", "data": 1, "sheets": ["survey_results"]}',
     "which no earlier record saved"),
    (b"[" * 50_000, "not a JSON record"),
    (b"", "not a JSON record"),
])
@pytest.mark.parametrize("where", ["middle", "last"])
def test_malformed_line_refuses_with_file_line_and_leaves_the_file(tmp_path, bad, why, where):
    path = tmp_path / "journal.jsonl"
    recs = [dumps(r).encode() for r in records()]
    at = 3 if where == "middle" else len(recs)
    lines = recs[:at] + [bad] + recs[at:]
    path.write_bytes(b"\n".join(lines) + b"\n")
    digest = sha(path)
    parse_error = why == "not a JSON record"
    if where == "last" and parse_error:  # a whole last line that does not parse: torn
        j = Journal(path, resume=True)
        j.close()
        assert j.torn_to is not None and j.torn_to.read_bytes() == bad + b"\n"
        return
    with pytest.raises(JournalError) as e:
        Journal(path, resume=True)
    assert str(e.value).startswith(f"{path}:{at + 1}: ") and why in str(e.value)
    assert "\n" not in str(e.value)
    assert sha(path) == digest and list(tmp_path.iterdir()) == [path]


def test_missing_or_directory_journal_is_a_journal_error(tmp_path):
    with pytest.raises(JournalError, match="no journal there"):
        Journal(tmp_path / "nope.jsonl", resume=True)
    with pytest.raises(JournalError, match="no journal there"):
        scan(tmp_path / "nope.jsonl")
    with pytest.raises(JournalError, match="a directory"):
        scan(tmp_path)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(n=hs.integers(1, 6), cut=hs.floats(0.0, 1.0))
def test_a_kill_at_any_byte_keeps_every_whole_record(tmp_path_factory, n, cut):
    """Cut a journal at any byte (a kill mid-write): resume keeps exactly the records whose
    newline was written, the rest goes to the side file, and appending goes on cleanly."""
    d = tmp_path_factory.mktemp("cut")
    path = d / "journal.jsonl"
    full = write(path, records(n))
    k = round(cut * len(full))
    path.write_bytes(full[:k])
    whole = full[:full.rfind(b"\n", 0, k) + 1]
    j = Journal(path, resume=True)
    assert [dumps(r).encode() + b"\n" for r in j.records] == whole.splitlines(keepends=True)
    assert path.read_bytes() == whole
    assert (j.torn_to.read_bytes() if j.torn_to else b"") == full[len(whole):k]
    j.append({"kind": "note", "event": "end"})
    j.close()
    assert scan(path).records[-1] == {"kind": "note", "event": "end"} and not scan(path).torn


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(line=hs.integers(0, 100), junk=hs.binary(min_size=1, max_size=40))
def test_junk_inside_a_journal_never_passes_silently(tmp_path_factory, line, junk):
    """Junk bytes (no newline) inserted at the start of any line but the last: either the
    line still parses as a record (then it is one), or the resume names that line and the
    file is unchanged."""
    d = tmp_path_factory.mktemp("junk")
    path = d / "journal.jsonl"
    lines = write(path, records(4)).splitlines(keepends=True)
    i = line % (len(lines) - 1)
    junk = junk.replace(b"\n", b" ")
    lines[i] = junk + lines[i]
    path.write_bytes(b"".join(lines))
    digest = sha(path)
    try:
        j = Journal(path, resume=True)
    except JournalError as e:
        assert str(e).startswith(f"{path}:{i + 1}: ")
        assert sha(path) == digest and sorted(os.listdir(d)) == ["journal.jsonl"]
        return
    j.close()
    assert len(j.records) == len(lines) and j.torn_to is None


def test_record_files_are_replaced_atomically_and_named_plainly(tmp_path):
    f = tmp_path / "results.json"
    write_json(f, {"a": 1})
    stale = tmp_path / f".results.tmp-{os.getpid() + 1}.json.part"  # a killed writer's
    stale.write_text("{")
    write_json(f, {"a": 2})
    assert json.loads(f.read_text()) == {"a": 2}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]
    with pytest.raises(RuntimeError), atomic_path(f) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed while writing")
    assert json.loads(f.read_text()) == {"a": 2}  # the old content stays whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]
    for name in ("../../X", "a/b", ".x", "", "x" * 200):
        with pytest.raises(ValueError, match="plain file name"):
            sheet_path(tmp_path, name)


def test_a_writer_clears_its_own_stale_temporaries_only(tmp_path):
    """By literal name: a name with glob characters has its temporaries cleared too, and a
    neighbour's are left alone."""
    odd = tmp_path / "r[1]*.json"
    mine = tmp_path / f".r[1]*.tmp-{os.getpid() + 1}.json.part"
    other = tmp_path / f".r[1]*x.tmp-{os.getpid() + 1}.json.part"
    for stale in (mine, other):
        stale.write_text("{")
    write_json(odd, {"a": 1})
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([odd.name, other.name])


def test_write_sheets_refuses_a_name_outside_the_directory(tmp_path):
    import simpy

    run = Run(VirtualClock(simpy.Environment()), Journal(tmp_path / "j.jsonl"))
    run.sheets["../../escape"] = {"x": 1}
    with pytest.raises(ValueError, match="outside the run directory"):
        write_sheets(tmp_path / "run", run)
    run.journal.close()
    assert not (tmp_path.parent / "escape.json").exists()
    assert not (tmp_path / "run" / "sheets").exists()


def test_a_run_block_is_heard_once_run_and_not_when_restored(tmp_path):
    """Run.block tells its listener a chart's data (its journal form) as soon as the chart
    has run, so a run can act on it meanwhile (the day's nonlinearity plot, issue 17); a
    block restored from the journal (skip mode) is not heard again. Run.meanwhile without a
    second process computes when the value is asked for, on the arguments as they were at
    the call: its error is met there, as when a second process loses the race."""
    import statistics

    import simpy

    heard: list[dict] = []
    clock = VirtualClock(simpy.Environment())
    j = Journal(tmp_path / "journal.jsonl")
    run = Run(clock, j, listener=heard.append, resume="skip")
    got = run.block("II-7", lambda: {"data": {1: [{"rate": 0.5}]}}, lambda v: v)
    assert got == {"data": {"1": [{"rate": 0.5}]}}
    assert [e for e in heard if e["kind"] == "block"] == [
        {"kind": "block", "key": "II-7", "data": {"data": {"1": [{"rate": 0.5}]}}}]
    xs = [1.0, 2.0]
    later = run.meanwhile("statistics:fmean", data=xs)
    xs.append(9.0)
    assert later() == 1.5
    empty = run.meanwhile("statistics:fmean", data=[])  # nothing raised yet
    with pytest.raises(statistics.StatisticsError):
        empty()
    j.close()
    heard.clear()
    again = Run(clock, Journal(tmp_path / "journal.jsonl", resume=True), listener=heard.append,
                resume="skip")
    assert again.block("II-7", lambda: pytest.fail("restored, not run"), lambda v: v) == got
    assert not [e for e in heard if e["kind"] == "block"]
