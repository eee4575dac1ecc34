"""`station report RUN_DIR`: the HTML report of a run, rendered from its record alone.

``build`` reads the run directory into plain tables (identity, verdict, results with their
simulation truth check apart, alignments, check-sheets, other sheets, plots); the Jinja2
template ``templates/report.html.j2`` lays them out. Nothing here looks at a live station.
"""

from __future__ import annotations

import base64
import functools
import json
import math
import re
import sys
from collections.abc import Collection
from pathlib import Path
from typing import TYPE_CHECKING, Any

from station.errors import UseError
from station.files import write_bytes

if TYPE_CHECKING:
    from jinja2 import Environment

    from procedures.runner import Beside

REPORT_NAME = "report.html"
RESULT_FILES = ("results.json", "gyrocompass.json", "esg.json", "gyrocompass_analysis.json")
LABORATORIES = {"results.json": "isu", "gyrocompass.json": "cigtf", "esg.json": "esg"}
TITLES = {
    "isu": "ISU calibration laboratory (report 000)",
    "cigtf": "CIGTF gyrocompassing test (report 001)",
    "esg": "ESG readout laboratory (report 004)",
}
# run.json's keys in the contract's order (issue 15)
IDENTITY_KEYS = ("run_uid", "laboratory", "command", "argv", "status", "reason", "chart",
                 "step", "verdict", "exit_code", "started_utc", "ended_utc", "version",
                 "vcs_revision", "seed", "config_file", "config_digest", "station_id", "unit",
                 "operator")
HEADER_KEYS = ("experiment", "principal_operator", "date", "identification", "sheets_used",
               "special_procedures")
# result lists, with the chart or section that defines them
TABLE_TITLES = {
    "calibration": "Calibration Results Sheet (Chart II-5)",
    "alignment": "Alignment results (Part III)",
    "runs": "Runs: theta and its standard error (section 5.2)",
    "phases": "Phases (eqs. 20-25)",
    "tests": "Significance tests (section 5.4)",
    "budget": "Error budget of theta (report 001, eqs. 26-27), arcsec",
    "setup": "What the pre-test set-up leaves (report 001, section 4.1)",
    "eq27 phases": "Phases corrected by eq. 27 (report 001, Appendix II)",
    "schedules": "Calibration schedules (pattern fit and readout)",
    "table4": "Calibration and readout errors (report 004, Table 4)",
    "order_trials": "Polynomial order trials, 5th to 9th (report 004, Data Reduction Technique)",
    "amplification": "Amplification of the readout error by strategy",
    "amplification_curve": "Amplification against pattern range (Figure 2)",
}
ALIGNMENT_KEYS = ("alignment",)
LABEL_KEYS = ("label", "instrument", "parameter", "method", "estimator", "phase", "run", "name",
              "strategy", "pattern", "range_deg")
FIRST_KEYS = ("units", "estimate", "sigma", "predicted_sigma_arcsec", "theta_arcsec",
              "sigma_arcsec", "limit_text", "verdict")
VERDICT_KEYS = ("limit", "limit_text", "verdict")
TRUTH_KEYS = ("truth", "error", "error_over_sigma", "truth_check", "T_true",
              "level_error_arcsec", "azimuth_error_arcsec")
PLOT_CAPTIONS = {
    "nonlinearity.png": "Gyro scale-factor nonlinearity (Chart II-7)",
    "gyrocompass.png": "Gyrocompassing error theta per run (report 001, section 5)",
    "esg_calibration.png": "ESG pattern calibration and readout errors (report 004)",
    "esg_strategy.png": "Readout error amplification against pattern range (report 004, "
                        "Figure 2)",
}


class ReportError(UseError):
    """A report that cannot be made as asked (no such run directory, no record in it, an
    unwritable output); one line naming the path (exit 2)."""


def _is_truth(key: str) -> bool:
    return key in TRUTH_KEYS or key.startswith("true_")


def fmt(value: Any, key: str = "") -> str:
    """A value as the report prints it: every digit the record holds that matters, never
    cut (numbers to 8 significant figures, errors and sigmas to 3)."""
    if value is None:
        return "\u2013"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if not math.isfinite(value):
            return str(value)
        digits = 3 if key in ("error", "sigma", "error_over_sigma", "error/sigma") else 8
        return format(value, f".{digits}g")
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(fmt(v, key) for v in value) + "]"
    if isinstance(value, dict):
        return ", ".join(f"{k}: {fmt(v, str(k))}" for k, v in value.items())
    return str(value)


def row_label(key: str, i: int, row: dict) -> str:
    """The row's name in the report (its ``data-row``): its identifying fields joined."""
    if isinstance(row.get("label"), str):
        return str(row["label"])
    parts = [fmt(row[k]) for k in LABEL_KEYS if k in row and row[k] is not None]
    return " ".join(parts) if parts else f"{key} {i + 1}"


def _verdict_class(text: str) -> str:
    t = text.upper()
    if t == "PASS":
        return "pass"
    if t == "FAIL":
        return "fail"
    return "nolimit" if t.startswith("NO LIMIT") else ""


def _num(value: Any) -> str:
    """The cell class of a value: numbers (and lists of them) right-aligned."""
    return "num" if isinstance(value, (int, float, list)) and not isinstance(value, bool) else ""


def _ordered(keys: list[str]) -> list[str]:
    first = [k for k in LABEL_KEYS if k in keys] + [k for k in FIRST_KEYS if k in keys]
    return first + [k for k in keys if k not in first]


def result_tables(key: str, rows: list[dict]) -> tuple[dict, dict | None]:
    """A result list as its table (label fields, estimate, sigma, limit, verdict, the rest)
    and, when the rows carry any truth, the simulation's truth-check table beside it."""
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    main = [k for k in _ordered(keys) if not _is_truth(k)
            and not (k == "limit" and "limit_text" in keys)]
    table: dict = {"key": key, "title": TABLE_TITLES.get(key, key.replace("_", " ")),
                   "columns": main, "rows": []}
    for i, r in enumerate(rows):
        cells = []
        for k in main:
            text = fmt(r.get(k), k)
            cells.append({"text": text, "cls": _verdict_class(text) if k == "verdict"
                          else _num(r.get(k))})
        table["rows"].append({"label": row_label(key, i, r), "cells": cells,
                              "cls": _verdict_class(str(r.get("verdict", "")))})
    truth_keys = [k for k in keys if _is_truth(k)]
    if not any(r.get(k) is not None for r in rows for k in truth_keys):
        return table, None
    z = "error" in keys and "sigma" in keys and "error_over_sigma" not in keys
    label_cols = [k for k in LABEL_KEYS if k in keys]
    cols = label_cols + [k for k in ("estimate",) if k in keys] + truth_keys
    truth: dict = {"key": key, "title": table["title"], "columns": cols + (["error/sigma"]
                   if z else []), "rows": []}
    for i, r in enumerate(rows):
        cells = [{"text": fmt(r.get(k), k), "cls": _num(r.get(k))} for k in cols]
        if z:
            e, s = r.get("error"), r.get("sigma")
            q = e / s if isinstance(e, (int, float)) and isinstance(s, (int, float)) and s \
                else None
            cells.append({"text": fmt(q, "error/sigma"),
                          "cls": "num beyond" if q is not None and abs(q) > 4 else "num"})
        tc = str(r.get("truth_check") or "")
        truth["rows"].append({"label": row_label(key, i, r), "cells": cells,
                              "cls": "beyond" if tc.startswith("beyond") else ""})
    return table, truth


def _read_json(path: Path, missing: list[str], texts: dict[str, str] | None = None) -> Any:
    """The JSON file's value (None, noted in ``missing``, when unreadable); ``texts`` keeps
    its text by stem when it is indented as the record writes it (laboratory.record): the
    report shows such a sheet as its file, not dumped again (issue 17: 14 ms of the day's
    report; the text is the same)."""
    try:
        text = path.read_text(encoding="utf-8")
        value = json.loads(text)
    except (OSError, UnicodeDecodeError, ValueError) as e:
        missing.append(f"{path.name}: unreadable ({type(e).__name__}), left out")
        return None
    if texts is not None and text.startswith("{\n \"") and text.endswith("}"):
        texts[path.stem] = text
    return value


# the end of a journal line that is a sheet record as procedures.journal writes it (sorted
# keys: the sheet's data first, then its kind, its name and the wall stamp): every pair it
# names is the record's own, at its top level (the final brace closes the record)
SHEET_LINE_END = re.compile(r'\},"kind":"sheet","name":"([^"\\]*)"(?:,"wall":"[^"\\]*")?\}')
SHEET_LINE_TAIL = 400  # characters of a long line that hold that end


def _journal_records(d: Path, skip_sheets: Collection[str] = ()) -> list[dict] | None:
    """The journal's records, read once for the whole report (a torn last line or a line
    that is no record left out); None without a journal. ``skip_sheets``: sheets the
    report has from sheets/, whose journal records (most of the journal's bytes: the
    alignments' parameter sheets are 110 KB a line) are left unparsed (issue 17)."""
    path = d / "journal.jsonl"
    if not path.is_file():
        return None
    records = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        if skip_sheets and len(line) > SHEET_LINE_TAIL:
            m = SHEET_LINE_END.search(line, len(line) - SHEET_LINE_TAIL)
            if m is not None and m.end() == len(line) and m[1] in skip_sheets:
                continue
        try:
            rec = json.loads(line)
        except ValueError:
            continue  # a torn last line
        if isinstance(rec, dict):
            records.append(rec)
    return records


def _journal_sheets(records: list[dict] | None) -> list[tuple[str, Any]]:
    """The sheets the journal holds (its sheet records, the last of each name): a stopped
    run's completed check-sheets, which it never wrote to sheets/."""
    found: dict[str, Any] = {}
    for rec in records or ():
        if rec.get("kind") == "sheet" and "name" in rec:
            found[str(rec["name"])] = rec.get("data")
    return list(found.items())


def _ending(identity: object) -> dict[str, Any]:
    """run.json's status, reason and (for a stop) chart and step; None each without it."""
    ident = identity if isinstance(identity, dict) else {}
    return {k: ident.get(k) for k in ("status", "reason", "chart", "step")}


def _journal_end(records: list[dict] | None) -> dict:
    """How the journal says the run ended: an end note, or the stop (its failed record) and
    the last step it recorded."""
    if records is None:
        return {"ended": None, "last_step": None, "failed": None}
    last, ended, failed = None, False, None
    for rec in records:
        if rec.get("kind") == "step":
            last = f"Chart {rec.get('chart')}, step {rec.get('step')}"
        if rec.get("kind") == "note" and rec.get("event") == "end":
            ended = True
        if rec.get("kind") == "failed":
            failed = str(rec.get("error"))
    return {"ended": ended, "last_step": last, "failed": failed}


def _sheet_sort_key(item: tuple[str, Any]) -> tuple[float, str]:
    name, s = item
    steps = (s.get("steps") or []) if isinstance(s, dict) else []
    t = steps[0].get("t_sim") if steps and isinstance(steps[0], dict) else None
    return (t if isinstance(t, (int, float)) else math.inf, name)


def check_sheet(name: str, s: dict) -> dict:
    """A check-sheet as the report shows it: chart, title, header, its ticked steps."""
    steps = []
    for st in s.get("steps") or []:
        reading = st.get("reading")
        steps.append({"number": fmt(st.get("number")), "text": fmt(st.get("text")),
                      "done": bool(st.get("done")), "t_sim": fmt(st.get("t_sim")),
                      "reading": "" if reading is None else json.dumps(reading,
                                                                       separators=(", ", ": "))})
    header = s.get("header")
    return {"name": name, "chart": fmt(s.get("chart")), "title": s.get("title") or "",
            "header": None if not isinstance(header, dict) else
            [(k.replace("_", " "), fmt(header.get(k))) for k in
             list(HEADER_KEYS) + [k for k in header if k not in HEADER_KEYS]],
            "steps": steps, "complete": all(x["done"] for x in steps) and bool(steps)}


def build(run_dir: Path) -> dict:
    """Everything the report shows, read from the run directory ``run_dir`` only."""
    d = Path(run_dir)
    missing: list[str] = []
    identity = _read_json(d / "run.json", missing) if (d / "run.json").is_file() else None
    if identity is None and not (d / "run.json").is_file():
        missing.append("run.json: absent (a record from before run identities): the run's "
                       "uid, command, version, configuration, unit and operator are unknown")
    results: dict[str, Any] = {}
    for name in RESULT_FILES:
        if (d / name).is_file():
            got = _read_json(d / name, missing)
            if isinstance(got, dict):
                results[name] = got
    lab = (identity or {}).get("laboratory") if isinstance(identity, dict) else None
    lab = lab or next((LABORATORIES[n] for n in results if n in LABORATORIES), None)
    if not any(n in results for n in LABORATORIES):
        missing.append("results: no results.json, gyrocompass.json or esg.json (the run "
                       "stopped or was interrupted before its results)")
    tables: list[dict] = []
    truth_tables: list[dict] = []
    alignments: list[dict] = []
    summaries: list[dict] = []
    truth_summaries: list[dict] = []
    figures: list[tuple[str, str, str]] = []
    verdict = None
    for name, res in results.items():
        if isinstance(res.get("verdict"), dict):
            verdict = verdict or res["verdict"]
        for key, value in res.items():
            if key == "verdict":
                continue
            if isinstance(value, list) and value and all(isinstance(r, dict) for r in value):
                t, tt = result_tables(key, value)
                t["source"] = name
                (alignments if key in ALIGNMENT_KEYS else tables).append(t)
                if tt is not None:
                    truth_tables.append(tt)
            elif isinstance(value, dict):
                flat = [(k, fmt(v, k)) for k, v in value.items()
                        if not (isinstance(v, list) and v and isinstance(v[0], dict))]
                title = f"{key.replace('_', ' ')} ({name})"
                known = [(k, v) for k, v in flat if key == "truth" or _is_truth(k)]
                flat = [(k, v) for k, v in flat if (k, v) not in known]
                if flat:
                    summaries.append({"title": title, "items": flat})
                if known and any(v != fmt(None) for _, v in known):
                    truth_summaries.append({"title": title, "items": known})
                for k, v in value.items():
                    if isinstance(v, list) and v and all(isinstance(r, dict) for r in v):
                        t, tt = result_tables(f"{key} {k}", v)
                        t["source"] = name
                        tables.append(t)
                        if tt is not None:
                            truth_tables.append(tt)
            elif not (isinstance(value, list) and value):
                figures.append((key, fmt(value, key), name))
    # the judged tables (a verdict column: what the run decides) before studies and extras
    tables.sort(key=lambda t: "verdict" not in t.get("columns", ()))
    ident_rows = []
    if isinstance(identity, dict):
        ident_rows = [(k, fmt(identity.get(k), k)) for k in IDENTITY_KEYS if k in identity]
        ident_rows += [(k, fmt(v, k)) for k, v in identity.items() if k not in IDENTITY_KEYS]
        if verdict is None and identity.get("verdict"):
            verdict = {"outcome": identity["verdict"], "failed": []}
    outcome = str(verdict.get("outcome")) if isinstance(verdict, dict) else None
    failed = [str(x) for x in (verdict or {}).get("failed") or []] if verdict else []
    checks, others = [], []
    sheets_dir = d / "sheets"
    loaded = []
    texts: dict[str, str] = {}  # a sheet file's text: what json.dumps(indent=1) gives again
    for f in sorted(sheets_dir.glob("*.json")) if sheets_dir.is_dir() else []:
        s = _read_json(f, missing, texts)
        if s is not None:
            loaded.append((f.stem, s))
    have = {name for name, _ in loaded}
    records = _journal_records(d, have)
    loaded += [(n, s) for n, s in _journal_sheets(records) if n not in have and s is not None]
    for name, s in sorted(loaded, key=_sheet_sort_key):
        if isinstance(s, dict) and "chart" in s and "steps" in s:
            checks.append(check_sheet(name, s))
        else:
            others.append({"name": name, "text": texts.get(name) or json.dumps(s, indent=1)})
    plots = []
    for p in sorted(d.glob("*.png")) + sorted(d.glob("plots/*.png")):
        try:
            data = base64.b64encode(p.read_bytes()).decode("ascii")
        except OSError:
            missing.append(f"{p.name}: unreadable, left out")
            continue
        plots.append({"name": str(p.relative_to(d)), "caption": PLOT_CAPTIONS.get(p.name, p.stem),
                      "src": f"data:image/png;base64,{data}"})
    config_text = None
    if (d / "config.toml").is_file():
        config_text = (d / "config.toml").read_text(encoding="utf-8", errors="replace")
    return {
        "run_dir": str(d), "laboratory": lab, "lab_title": TITLES.get(lab or "", lab or
                                                                      "unknown laboratory"),
        "identity": ident_rows, **_ending(identity),
        "journal": _journal_end(records), "outcome": outcome, "outcome_cls":
        _verdict_class(outcome or ""), "failed": failed, "missing": missing,
        "tables": tables, "truth_tables": truth_tables, "alignments": alignments,
        "summaries": summaries, "truth_summaries": truth_summaries, "figures": figures,
        "checks": checks, "others": others,
        "plots": plots, "config_text": config_text, "history": _history(d),
    }


def _history(d: Path) -> dict[str, Any]:
    """The "History of this unit" section (laboratory/history/section.py); its one line
    when the history cannot be had, never the report's failure."""
    try:
        from laboratory.history.section import safe_history_section
    except Exception as e:  # noqa: BLE001 - the report never fails because of the history
        return {"shown": False, "text": f"No history: the calibration history is unavailable "
                f"({type(e).__name__}: {e})"}
    return safe_history_section(d)


@functools.cache
def _environment() -> Environment:
    """The templates' environment, one per process; jinja2 is imported here, when a report
    is about to be written, not when a command starts."""
    from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape

    return Environment(loader=PackageLoader("laboratory.report", "templates"),
                       autoescape=select_autoescape(default=True, default_for_string=True),
                       undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True)


def prepare_report() -> None:
    """Import jinja2 and compile the report's templates (the one it includes too) and
    import the history section's modules now: a run calls it while its plot child draws,
    so that ``report_after`` does not pay for them after the record closes. An error is
    left for ``report_after`` to meet and report."""
    try:
        env = _environment()
        for name in ("report.html.j2", "history.html.j2"):
            env.get_template(name)
        import laboratory.history.lite  # noqa: F401 - imported now, used by _history
        import laboratory.history.section  # noqa: F401 - imported now, used by _history
    except Exception:  # noqa: BLE001, S110 - report_after reports it when it writes
        pass


def render_report(run_dir: Path) -> str:
    """The report of the run in ``run_dir`` as one self-contained HTML document."""
    d = Path(run_dir)
    if not d.is_dir():
        raise ReportError(f"RUN_DIR {d}: no such directory")
    from laboratory.rundir import holds_record

    if not holds_record(d):
        raise ReportError(f"RUN_DIR {d}: no run record there (no journal, sheets or results)")
    return _environment().get_template("report.html.j2").render(**build(d))


def render_history_page(history: dict[str, Any], db: str, since: str | None) -> str:
    """`station trend --html`: the report's "History of this unit" section as a page."""
    return _environment().get_template("trend.html.j2").render(history=history, db=db,
                                                               since=since)


def write_report(run_dir: Path, out: Path | None = None) -> Path:
    """Render the report of ``run_dir`` into ``out`` (default RUN_DIR/report.html),
    atomically; returns the file written."""
    html = render_report(run_dir)
    target = Path(out) if out is not None else Path(run_dir) / REPORT_NAME
    if target.is_dir():
        raise ReportError(f"--out {target} is a directory, not a file")
    try:
        write_bytes(target, html.encode("utf-8"))
    except OSError as e:
        raise ReportError(f"--out {target}: cannot write: {e.strerror or e}") from None
    return target


# The same two functions as jobs for a run's plot child (laboratory.plot_worker), which
# imports jinja2 and compiles the template while it is idle and writes the report while
# this process waits (issue 17: 0.1-0.15 s off the end of `station day`).
PREPARE_JOB = "laboratory.report.html:prepare_report"
WRITE_JOB = "laboratory.report.html:write_report"


def report_after(run_dir: Path, beside: Beside | None = None) -> None:
    """What every run command calls at its end, however the run ended: the report of what
    the record holds (nothing when the directory holds no record). A report that cannot be
    written is a warning on stderr, never the run's failure. ``beside``: a plot child that
    writes it (``WRITE_JOB``; here if the child cannot), with the same file."""
    from laboratory.rundir import holds_record

    try:
        if Path(run_dir).is_dir() and holds_record(Path(run_dir)):
            if beside is None:
                write_report(run_dir)
            else:
                beside.compute(WRITE_JOB, {"run_dir": Path(run_dir)})()
    except Exception as e:  # noqa: BLE001 - the run's own outcome must come through
        print(f"warning: {Path(run_dir) / REPORT_NAME} not written: {e}", file=sys.stderr)
