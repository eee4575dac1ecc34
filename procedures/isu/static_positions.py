"""The shape shared by Charts II-11..II-14: patch, set the mode, then at each position set
the table with level corrections, preset the counters, run them, record.

The gyro sheets (II-11, II-12) and the accelerometer sheets (II-13, II-14) differ only in
what is patched, the counter mode, the presets and what a reading means (``StaticKind``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from procedures.isu.common import (
    Gate,
    PositionSet,
    check_repeated_counts,
    patch,
    run_counters,
    set_modes,
    set_position,
)
from procedures.isu.readings import resolver
from procedures.isu.settings import wiring
from procedures.isu.sheets import CounterOutputs, CounterSettings, ResolverSettings
from procedures.runner import CheckSheetRun, Run
from station.config.calibration import set_to

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers


@dataclass(frozen=True)
class StaticKind:
    experiment: str  # Counter Connections Sheet experiment (procedures.isu.settings)
    counters: tuple[int, ...]
    mode: str  # "measure Z" | "measure X-Y"
    sheet_key: str  # "gyro" | "accel": row prefix on the settings and outputs sheets
    patch_text: str
    preset_text: str
    operate_text: str
    record_text: str
    timeout: Callable[[dict[int, int]], float]
    record: Callable[[dict[int, int], Gate, PositionSet], dict]
    repeats: dict[int, int] = field(default_factory=dict)  # check counter -> counter
    gate_s: Callable[[dict[int, int]], float] = lambda n: 0.0
    # steps 7-8 done otherwise (II-5.2's pulse gate, procedures.isu.pulse_gate):
    # (drivers, sheet, position, step tag, presets, the setting) -> (gate, the position's
    # record; its "outputs", if any, the Counter Outputs rows)
    measure: Callable[[IsuDrivers, CheckSheetRun, int, str, dict[int, int], PositionSet],
                      tuple[Gate, dict]] | None = None
    n_counters: int = 6  # the rack's counters (the simultaneous experiment's wiring)


def pair_steps(pairs: Iterable[int]) -> list[tuple[int, str, str]]:
    """Positions m, m + 1 for each m: set (step 6), then turn phi3 by 180 deg (step 10)."""
    out = []
    for m in pairs:
        out.append((m, "6", f"Set phi3, phi4 to position {m} with level correction"))
        out.append((m + 1, "10", f"Turn phi3 by 180 deg: position {m + 1} (level re-read)"))
    return out


def single_steps(positions: Iterable[int]) -> list[tuple[int, str, str]]:
    return [(m, "6", f"Set phi3, phi4 to position {m} with level correction") for m in positions]


@dataclass(frozen=True)
class Uncorrected:
    """Positions set without bubble-level corrections (II-6.1's option): phi1 and phi3 carry
    the survey's level corrections (Chart I-2 step 5, deg), read at ``t_level`` (s), the
    instant a gate's tilt then counts from."""

    phi1_deg: float
    phi3_deg: float
    t_level: float

    def text(self, text: str) -> str:
        """A step's text for an uncorrected setting."""
        return (text.replace("plus level correction", "plus the survey's level correction")
                .replace("with level correction", "with the survey's level correction")
                .replace("(level re-read)", "(no level reading)"))


def _set(st: IsuDrivers, phi3: float, phi4: float, unc: Uncorrected | None,
         precision_arcsec: float = 0.0) -> PositionSet:
    """Set phi1 = 0, phi2 = 90 and (phi3, phi4) to ``precision_arcsec`` (II-6.1): levelled,
    or with the survey's corrections."""
    phi3, phi4 = set_to(phi3, precision_arcsec), set_to(phi4, precision_arcsec)
    if unc is None:
        return set_position(st, 0.0, 90.0, phi3, phi4, level=True)
    ps = set_position(st, unc.phi1_deg, 90.0, phi3 + unc.phi3_deg, phi4, level=False)
    ps.t_level = unc.t_level
    return ps


def run_static(st: IsuDrivers, run: Run, chart: str, title: str, kind: StaticKind,
               settings: ResolverSettings, presets: CounterSettings, outputs: CounterOutputs,
               steps: list[tuple[int, str, str]], uncorrected: Uncorrected | None = None,
               precision_arcsec: float = 0.0) -> dict[int, dict]:
    """One static chart; ``uncorrected``: set every position without bubble corrections;
    ``precision_arcsec``: the resolver-setting precision of its positions (II-6.1)."""
    unc = uncorrected
    data: dict[int, dict] = {}
    with run.sheet(chart, title) as sheet:
        sheet.done("1", "Resolver and counter settings available")
        sheet.done("2", "Turn-on procedures complete (Chart I-1)")
        with sheet.step("3", kind.patch_text):
            patch(st, wiring(kind.experiment, kind.n_counters))
        counters = f"{kind.counters[0]}-{kind.counters[-1]}"
        every = (*kind.counters, *kind.repeats)
        also = (f" (and {', '.join(str(c) for c in kind.repeats)} counting again)"
                if kind.repeats else "")
        with sheet.step("4", f"Set counters {counters} to {kind.mode}{also}"):
            set_modes(st, every, kind.mode)
        text5 = "Set phi1 to 0 deg plus level correction, phi2 to 90 deg"
        with sheet.step("5", text5 if unc is None else unc.text(text5)) as s:
            p3 = resolver(st, 3) - (0.0 if unc is None else unc.phi3_deg)
            ps = _set(st, p3, resolver(st, 4), unc)
            s.reading = ps.reading()
        for m, first, text in steps:
            tag = f"/m{m}"
            p = settings.positions[str(m)]
            with sheet.step(first + tag, text if unc is None else unc.text(text)) as s:
                ps = _set(st, p.phi3, p.phi4, unc, precision_arcsec)
                s.reading = {"phi1": ps.phi[0], "phi3": ps.phi[2], "phi4": ps.phi[3],
                             **ps.reading()}
            row = presets.presets[f"{kind.sheet_key} {m}"]
            n = {c: int(row[str(c)]) for c in every}
            if kind.measure is not None:
                gate, record = kind.measure(st, sheet, m, tag, n, ps)
                with sheet.step("9" + tag, kind.record_text) as s:
                    rows = record.pop("outputs", None) or {
                        f"{kind.sheet_key} {m}": {str(c): v for c, v in gate.readings.items()}}
                    outputs.outputs.update(rows)
                    data[m] = record
                    s.reading = record
                continue
            with sheet.step("7" + tag, kind.preset_text) as s:
                s.reading = {str(c): v for c, v in n.items()}
            with sheet.step("8" + tag, kind.operate_text) as s:
                gate = run_counters(st, n, kind.timeout(n))
                check_repeated_counts(st, gate, kind.repeats, kind.gate_s(n))
                s.reading = {str(c): v for c, v in gate.readings.items()}
            with sheet.step("9" + tag, kind.record_text) as s:
                outputs.outputs[f"{kind.sheet_key} {m}"] = {
                    str(c): v for c, v in gate.readings.items()
                }
                data[m] = kind.record(n, gate, ps)
                s.reading = data[m]
    return data
