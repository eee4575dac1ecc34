"""Regression baselines: hold a procedure's new run against a stored earlier run.

``station regress save RUN_DIR BASELINE`` keeps every result row's estimate and sigma and
every sheet's steps (readings and simulated times) with the run's seed and config digest.
``station regress check RUN_DIR BASELINE`` compares a new run with it: each constant in
units of the combined sigma, z = (x_run - x_base) / sqrt(s_run^2 + s_base^2), a regression
beyond ``k``; each sheet exactly, but only where the two runs are deterministic replays of
each other (same laboratory, seed and config digest, both in virtual time). The outcome is
also a JUnit XML file (one testcase per constant and per sheet) that CI systems read.
See docs/regression.md.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from laboratory.record import write_json
from station.files import write_bytes

FORMAT = "station-regress-baseline"
VERSION = 1
DEFAULT_SIGMA = 4.0  # a regression: |z| beyond this many combined sigma


def _read(f: Path) -> Any:
    try:
        return json.loads(f.read_bytes())
    except FileNotFoundError:
        raise FileNotFoundError(f"{f}: no such file") from None
    except OSError as e:
        raise ValueError(f"{f}: cannot read it ({e.strerror})") from None
    except (ValueError, RecursionError) as e:
        raise ValueError(f"{f}: not JSON ({' '.join(str(e).split())})") from None


def _constant(name: str, units: str | None, estimate: Any, sigma: Any) -> dict[str, Any]:
    return {"name": name, "units": units or "-", "estimate": estimate, "sigma": sigma}


def constants(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Every estimated quantity of a laboratory's results file with its sigma: Chart II-5's
    rows and the alignments' errors (ISU), the phases' theta (CIGTF), the schedules'
    readout rms (ESG, no sigma: compared exactly where the runs are deterministic)."""
    out = []
    for r in results.get("calibration") or ():
        out.append(_constant(f"{r['instrument']}.{r['parameter']}", r.get("units"),
                             r.get("estimate"), r.get("sigma")))
    for e in results.get("alignment") or ():
        if "skipped" in e or e.get("level_error_arcsec") is None:
            continue  # no truth (a real laboratory): the attitude has no error to hold
        errors = [*e["level_error_arcsec"], e["azimuth_error_arcsec"]]
        for axis, x, s in zip(("E", "N", "az"), errors, e["predicted_sigma_arcsec"],
                              strict=True):
            out.append(_constant(f"{e['method']}/{e['estimator']} alignment.{axis} error",
                                 "arcsec", x, s))
    for p in results.get("phases") or ():
        out.append(_constant(f"{p['phase']} phase.theta", "arcsec", p.get("theta_arcsec"),
                             p.get("sigma_arcsec")))
    for s in results.get("schedules") or ():
        out.append(_constant(f"schedule {s['name']}.readout rms", "arcsec",
                             s.get("readout_rms_arcsec"), None))
    return out


RESULT_FILES = ("results.json", "gyrocompass.json", "esg.json")


def _sheet_content(sheet: Any) -> Any:
    """What of a sheet a deterministic replay must repeat exactly: a check-sheet's steps
    (number, reading, simulated time), any other sheet without its header (date, operator)."""
    if isinstance(sheet, dict) and isinstance(sheet.get("steps"), list):
        return [{"number": s.get("number"), "reading": s.get("reading"),
                 "t_sim": s.get("t_sim")} for s in sheet["steps"]]
    if isinstance(sheet, dict):
        return {k: v for k, v in sheet.items() if k != "header"}
    return sheet


def record_of(run_dir: Path) -> dict[str, Any]:
    """A completed run's baseline: identity, constants and sheets (ValueError naming the
    file for a run that is not complete or holds no results)."""
    d = Path(run_dir)
    if not d.is_dir():
        raise FileNotFoundError(f"{d}: no such run directory")
    ident = _read(d / "run.json")
    if ident.get("status") != "completed":
        raise ValueError(f"{d / 'run.json'}: status is {ident.get('status')!r}: only a "
                         "completed run is held against a baseline")
    results: dict[str, Any] | None = None
    for name in RESULT_FILES:
        if (d / name).is_file():
            results = _read(d / name)
            break
    if results is None:
        raise FileNotFoundError(f"{d} holds no results file ({', '.join(RESULT_FILES)})")
    sheets = {f.stem: _sheet_content(_read(f)) for f in sorted((d / "sheets").glob("*.json"))}
    return {
        "format": FORMAT, "version": VERSION, "source": str(d),
        "laboratory": ident.get("laboratory"), "command": ident.get("command"),
        "unit": ident.get("unit"), "seed": ident.get("seed"),
        "config_digest": ident.get("config_digest"),
        "virtual": results.get("links") is None,  # over links the readings are not replays
        "constants": constants(results), "sheets": sheets,
    }


def save(run_dir: Path, baseline: Path) -> dict[str, Any]:
    """Write ``run_dir``'s baseline to ``baseline`` (JSON, atomically); returns it."""
    rec = record_of(run_dir)
    Path(baseline).parent.mkdir(parents=True, exist_ok=True)
    write_json(Path(baseline), rec)
    return rec


def load(baseline: Path) -> dict[str, Any]:
    """A baseline file; ValueError naming the file and field if it is not one."""
    b = _read(Path(baseline))
    if not isinstance(b, dict) or b.get("format") != FORMAT:
        raise ValueError(f"{baseline}: format: not a {FORMAT} file")
    if b.get("version") != VERSION:
        raise ValueError(f"{baseline}: version: {b.get('version')!r}, this station reads "
                         f"version {VERSION}")
    for key in ("constants", "sheets"):
        if key not in b:
            raise ValueError(f"{baseline}: {key}: missing")
    return b


@dataclass(frozen=True)
class Case:
    """One testcase: a constant or a sheet; ``failure`` (a regression) or ``skipped`` says
    why, ``z`` the constant's change in combined sigma."""

    kind: str  # "constant" | "sheet"
    name: str
    failure: str | None = None
    skipped: str | None = None
    z: float | None = None


def _z(base: dict[str, Any], new: dict[str, Any]) -> float | None:
    sb, sn = base.get("sigma"), new.get("sigma")
    if not sb or not sn:
        return None
    return (new["estimate"] - base["estimate"]) / math.hypot(sb, sn)


def _constant_case(base: dict[str, Any], new: dict[str, Any] | None, k: float,
                   replay: bool) -> Case:
    name = base["name"]
    if new is None:
        return Case("constant", name, failure=f"{name}: absent from the run")
    xb, xn = base.get("estimate"), new.get("estimate")
    if xb is None and xn is None:
        return Case("constant", name, skipped="not determined in either run")
    if xb is None or xn is None:
        which = "the run" if xn is None else "the baseline"
        return Case("constant", name, failure=f"{name}: not determined in {which}")
    z = _z(base, new)
    if z is None:  # no sigma: only a deterministic replay can hold it, exactly
        if not replay:
            return Case("constant", name, skipped="no sigma, and the runs are not replays")
        if xb != xn:
            return Case("constant", name, failure=f"{name}: {xn!r} differs from the "
                        f"baseline's {xb!r} (no sigma; the runs are replays)")
        return Case("constant", name)
    if abs(z) > k:
        combined = math.hypot(base["sigma"], new["sigma"])
        return Case("constant", name, z=z, failure=(
            f"{name}: z = {z:+.2f} beyond {k:g} sigma (run {xn:.8g}, baseline {xb:.8g} "
            f"{base.get('units', '')}, combined sigma {combined:.3g})"))
    return Case("constant", name, z=z)


def _first_difference(a: Any, b: Any, where: str = "") -> str | None:
    """The path of the first value that differs between two JSON values, else None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b)):
            if key not in a or key not in b:
                return f"{where}.{key}".lstrip(".")
            d = _first_difference(a[key], b[key], f"{where}.{key}")
            if d is not None:
                return d
        return None
    if isinstance(a, list) and isinstance(b, list):
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            label = x.get("number") if isinstance(x, dict) and "number" in x else i
            d = _first_difference(x, y, f"{where}[{label}]")
            if d is not None:
                return d
        return None if len(a) == len(b) else f"{where} (length {len(b)}, baseline {len(a)})"
    return None if a == b else (where.lstrip(".") or "value")


def _sheet_case(name: str, base: Any, new: Any, replay: str | None) -> Case:
    if replay is not None:
        return Case("sheet", name, skipped=replay)
    if new is None:
        return Case("sheet", name, failure=f"sheet {name}: absent from the run")
    where = _first_difference(base, new)
    if where is not None:
        return Case("sheet", name, failure=f"sheet {name}: {where} differs from the baseline "
                    "(same seed and config digest: the sheet should repeat exactly)")
    return Case("sheet", name)


def _not_replay(base: dict[str, Any], new: dict[str, Any]) -> str | None:
    """Why the two runs' sheets need not repeat exactly (None: they must)."""
    for key in ("seed", "config_digest"):
        if base.get(key) != new.get(key):
            return f"not a replay: {key} differs from the baseline's"
    if not (base.get("virtual") and new.get("virtual")):
        return "not a replay: a run over links (real time)"
    return None


def check(run_dir: Path, baseline: Path, k: float = DEFAULT_SIGMA) -> list[Case]:
    """Every constant and sheet of the baseline held against ``run_dir``; a baseline of
    another laboratory, command or unit is refused (ValueError naming the field)."""
    if not k > 0:
        raise ValueError(f"--sigma must be > 0, got {k:g}")
    base, new = load(baseline), record_of(run_dir)
    for key in ("laboratory", "command", "unit"):
        if base.get(key) != new.get(key):
            raise ValueError(f"{baseline}: {key}: the baseline's {base.get(key)!r} is not "
                             f"the run's {new.get(key)!r}")
    replay = _not_replay(base, new)
    by_name = {c["name"]: c for c in new["constants"]}
    cases = [_constant_case(c, by_name.get(c["name"]), k, replay is None)
             for c in base["constants"]]
    known = {c["name"] for c in base["constants"]}
    cases += [Case("constant", n, failure=f"{n}: new in the run, not in the baseline")
              for n in by_name if n not in known]
    cases += [_sheet_case(n, s, new["sheets"].get(n), replay)
              for n, s in sorted(base["sheets"].items())]
    return cases


def junit_xml(cases: list[Case], suite: str = "station regress") -> bytes:
    """The cases as a JUnit XML document: one testsuite, a testcase per constant (class
    ``regress.constant``) and per sheet (``regress.sheet``)."""
    failures = sum(c.failure is not None for c in cases)
    skipped = sum(c.skipped is not None for c in cases)
    root = ET.Element("testsuites", name=suite, tests=str(len(cases)),
                      failures=str(failures), errors="0", skipped=str(skipped))
    ts = ET.SubElement(root, "testsuite", name=suite, tests=str(len(cases)),
                       failures=str(failures), errors="0", skipped=str(skipped))
    for c in cases:
        tc = ET.SubElement(ts, "testcase", classname=f"regress.{c.kind}", name=c.name)
        if c.z is not None:
            props = ET.SubElement(tc, "properties")
            ET.SubElement(props, "property", name="z", value=f"{c.z:.6g}")
        if c.failure is not None:
            f = ET.SubElement(tc, "failure", message=c.failure, type="regression")
            f.text = c.failure
        elif c.skipped is not None:
            ET.SubElement(tc, "skipped", message=c.skipped)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def write_junit(path: Path, cases: list[Case]) -> None:
    """The JUnit XML file, atomically."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_bytes(Path(path), junit_xml(cases))
