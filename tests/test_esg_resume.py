"""Resume of the ESG calibration over links (skip mode): completed blocks restored.

A served rack cannot replay hours of rotor time, so the acquisition is journaled in
blocks (ESG-DP, mount check, spinning-rotor set-up, each tilt and each scan). These tests
run the skip mode on virtual racks: the same rack continued (a station process that died
while the rack ran on, the same served session) and a new rack of the same seed (another
session: the processor's zero and the rotor are lost, so only the mount check is kept).
"""

from __future__ import annotations

import pytest

import procedures.esg.acquisition as acquisition
from procedures.esg.acquisition import RENEW, acquire
from procedures.journal import Journal, scan
from procedures.runner import ProcedureError, Run
from sim.esg.world import EsgParams
from station.racks.esg import EsgRack, open_esg_drivers

SEED = 11
PLAN = acquisition.EsgPlan(latitude_deg=EsgParams().latitude_deg)
STOP_IN = "11+"  # the scan the link is lost in, after STOP_AFTER of its readings
STOP_AFTER = 12


def _station(seed: int):
    rack = EsgRack(seed, EsgParams())
    return rack, open_esg_drivers(rack)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    rack, st = _station(SEED)
    j = Journal(tmp_path_factory.mktemp("esg") / "journal.jsonl")
    run = Run(st.clock, j)
    acq = acquire(st, run, PLAN)
    j.close()
    return acq, run


@pytest.fixture
def interrupted(tmp_path, monkeypatch):
    """A run whose processor link fails inside scan STOP_IN; (rack, station, journal)."""
    rack, st = _station(SEED)
    path = tmp_path / "journal.jsonl"
    current: dict[str, object] = {"scan": None, "reads": 0}
    real_scan, real_read = acquisition.run_scan, acquisition._read

    def run_scan(st_, plan, sh, acq, name, *a, **k):
        current["scan"], current["reads"] = name, 0
        return real_scan(st_, plan, sh, acq, name, *a, **k)

    def read(st_, plan, pickoffs):
        if current["scan"] == STOP_IN:
            current["reads"] = int(current["reads"]) + 1  # type: ignore[call-overload]
            if current["reads"] > STOP_AFTER:
                raise OSError("processor link lost")
        return real_read(st_, plan, pickoffs)

    monkeypatch.setattr(acquisition, "run_scan", run_scan)
    monkeypatch.setattr(acquisition, "_read", read)
    j = Journal(path)
    with pytest.raises(ProcedureError, match=r"ESG-CAL, step 11\+\.(0[2-9]|1).*link lost"):
        acquire(st, Run(st.clock, j, resume="skip"), PLAN)
    j.close()
    monkeypatch.undo()
    return rack, st, path


def _resume(st, path, repeat=()):
    j = Journal(path, resume=True)
    run = Run(st.clock, j, resume="skip", repeat=repeat)
    acq = acquire(st, run, PLAN)
    j.close()
    return acq, run


def _same_sheet_as(run, ref_run):
    steps = [s.number for s in run.check_sheets["ESG-CAL"].steps]
    assert steps == [s.number for s in ref_run.check_sheets["ESG-CAL"].steps]
    assert set(run.check_sheets) == set(ref_run.check_sheets)


def test_same_session_restores_every_completed_block(interrupted, uninterrupted):
    _, st, path = interrupted
    ref, ref_run = uninterrupted
    t_stop = st.clock.now()
    acq, run = _resume(st, path)
    assert run.restored == ["ESG-DP", "ESG-CAL.mount", "ESG-CAL.rotor", "ESG-CAL.scan-9",
                            "ESG-CAL.tilt-10", "ESG-CAL.scan-10+", "ESG-CAL.scan-10-",
                            "ESG-CAL.tilt-11"]
    _same_sheet_as(run, ref_run)
    # restored values are the interrupted run's, bit for bit (it measured the same rack as
    # the uninterrupted run until the stop, in the same virtual time)
    assert acq.cr_eq == ref.cr_eq and acq.t_zero_s == ref.t_zero_s
    assert [s.name for s in acq.scans] == [s.name for s in ref.scans]
    for a, b in zip(acq.scans[:3], ref.scans[:3], strict=True):
        assert [p.setting.cr for p in a.points] == [p.setting.cr for p in b.points]
    # the repeated and later scans were measured after the stop, on the running rotor:
    # same settings, count ratios within the line noise of the uninterrupted run's
    for a, b in zip(acq.scans[3:], ref.scans[3:], strict=True):
        assert [p.offset_deg for p in a.points] == [p.offset_deg for p in b.points]
        assert min(p.setting.t_s for p in a.points) > t_stop - 1.0 or a.name != STOP_IN
        for p, q in zip(a.points, b.points, strict=True):
            assert p.setting.cr[2] == pytest.approx(q.setting.cr[2], abs=3e-4)
    assert not scan(path).torn


def test_new_session_keeps_only_the_mount_check(interrupted, uninterrupted):
    _, old_st, path = interrupted
    ref, ref_run = uninterrupted
    rack, st = _station(SEED)  # the rack restarted: rotor stopped, processor unset
    acq, run = _resume(st, path, repeat=RENEW)
    assert run.restored == ["ESG-CAL.mount"]
    _same_sheet_as(run, ref_run)
    assert acq.mount_coning_arcsec == ref.mount_coning_arcsec
    # everything after the mount check measured again on the new rack (same world; the
    # skipped mount turns shift the time line, so the noise differs): within the count
    # ratios' tolerance of the uninterrupted run, with the same scans and settings
    assert acq.cr_eq == pytest.approx(ref.cr_eq, abs=3e-5)
    assert acq.unbalance_k_deg_hr == pytest.approx(ref.unbalance_k_deg_hr, rel=0.01)
    assert [(s.name, [p.offset_deg for p in s.points]) for s in acq.scans] == [
        (s.name, [p.offset_deg for p in s.points]) for s in ref.scans]


def test_a_block_with_malformed_steps_refuses_the_resume(interrupted):
    _, _, path = interrupted
    lines = path.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if '"key": "ESG-CAL.mount"' in ln
             or '"key":"ESG-CAL.mount"' in ln)
    lines[i] = lines[i].replace('"t_sim"', '"t_simx"', 1)
    path.write_text("\n".join(lines) + "\n")
    before = path.read_bytes()
    from procedures.journal import JournalError
    with pytest.raises(JournalError, match=rf":{i + 1}: block 'ESG-CAL.mount' carries steps"):
        Journal(path, resume=True)
    assert path.read_bytes() == before
