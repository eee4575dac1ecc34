"""An earlier run's sheets carried into a new one (`station day --prior RUN_DIR`,
`--survey RUN_DIR`): its Calibration Results Sheet (Chart II-5) or Survey Results Sheet
(Chart I-3), accepted only from a completed run of the same unit (run.json ``unit`` equal to
the config's ``[identity.unit]``) started at most ``[identity] max_prior_age_days`` ago.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from procedures.isu.carry_forward import PriorSheet
from procedures.isu.sheets import CalibrationResults, SurveyResults, sheets_used
from station.config.isu import StationConfig
from station.errors import BadArgument

# an earlier run that cannot be carried forward (unit, age, status or its sheet): the
# `--prior` / `--survey` argument cannot be used as given (exit 2)
PriorRefused = BadArgument


@dataclass(frozen=True)
class PriorRun:
    """An accepted earlier run: its directory, run.json and the sheet's source label."""

    path: Path
    record: dict[str, Any]

    @property
    def run_uid(self) -> str:
        return str(self.record["run_uid"])

    def source(self, chart: str) -> str:
        """How notes and "sheets used" cite a sheet of this run."""
        return f"Chart {chart} of run {self.run_uid} ({self.path.name})"


def _read_json(path: Path, option: str) -> Any:
    try:
        return json.loads(path.read_bytes())
    except FileNotFoundError:
        raise PriorRefused(f"{option}: {path} does not exist") from None
    except (OSError, ValueError) as e:
        raise PriorRefused(f"{option}: {path} is unreadable: {e}") from None


def accepted_run(run_dir: Path, cfg: StationConfig, option: str,
                 now: dt.datetime | None = None) -> PriorRun:
    """The earlier run in ``run_dir`` if it may be carried forward, else PriorRefused
    naming what does not match: its laboratory, status, unit serial or age."""
    run_dir = Path(run_dir)
    rec = _read_json(run_dir / "run.json", option)
    if not isinstance(rec, dict) or not isinstance(rec.get("run_uid"), str):
        raise PriorRefused(f"{option}: {run_dir / 'run.json'} has no run_uid")
    if rec.get("laboratory") != "isu":
        raise PriorRefused(f"{option}: {run_dir} is a {rec.get('laboratory')!r} run, not an "
                           "ISU calibration")
    if rec.get("status") != "completed":
        raise PriorRefused(f"{option}: {run_dir} did not complete (status "
                           f"{rec.get('status')!r})")
    want = cfg.identity.unit.model_dump()
    unit = rec.get("unit")
    have: dict[str, Any] = unit if isinstance(unit, dict) else {}
    for name, serial in want.items():
        if have.get(name) != serial:
            raise PriorRefused(f"{option}: unit {name} of {run_dir} is {have.get(name)!r}, "
                               f"the config's [identity.unit] {name} is {serial!r}")
    try:
        started = dt.datetime.fromisoformat(str(rec.get("started_utc")))
    except ValueError:
        raise PriorRefused(f"{option}: {run_dir / 'run.json'} started_utc "
                           f"{rec.get('started_utc')!r} is not a date") from None
    if started.tzinfo is None:
        started = started.replace(tzinfo=dt.UTC)
    age = ((now or dt.datetime.now(dt.UTC)) - started).total_seconds() / 86400.0
    limit = cfg.identity.max_prior_age_days
    if age > limit:
        raise PriorRefused(f"{option}: {run_dir} started {age:.1f} days ago, more than "
                           f"[identity] max_prior_age_days = {limit:g}")
    return PriorRun(run_dir, rec)


def load_prior(run_dir: Path, cfg: StationConfig, now: dt.datetime | None = None
               ) -> tuple[PriorRun, PriorSheet]:
    """`--prior RUN_DIR`: the earlier run and its Calibration Results Sheet."""
    run = accepted_run(run_dir, cfg, "--prior", now)
    path = run.path / "sheets" / "calibration_results.json"
    try:
        sheet = CalibrationResults.model_validate(_read_json(path, "--prior"))
    except ValidationError as e:
        raise PriorRefused(f"--prior: {path} is not a Calibration Results Sheet: "
                           f"{e.errors()[0]['msg']}") from None
    return run, PriorSheet(sheet, run.source("II-5"))


def load_survey(run_dir: Path, cfg: StationConfig, now: dt.datetime | None = None
                ) -> tuple[PriorRun, SurveyResults]:
    """`--survey RUN_DIR`: the earlier run and its Survey Results Sheet (its own heading
    dropped: the new run heads it, citing the source in "sheets used")."""
    run = accepted_run(run_dir, cfg, "--survey", now)
    path = run.path / "sheets" / "survey_results.json"
    try:
        sv = SurveyResults.model_validate(_read_json(path, "--survey"))
    except ValidationError as e:
        raise PriorRefused(f"--survey: {path} is not a Survey Results Sheet: "
                           f"{e.errors()[0]['msg']}") from None
    return run, sv.model_copy(update={"header": None})


# sheets whose "Sheet Used" cite the earlier Calibration / Survey Results Sheet
_CITE_PRIOR = ("calibration_results", "check_II-15")
_CITE_SURVEY = ("survey_results", "resolver_settings", "calibration_results", "check_II-15",
                "alignment_results")


@dataclass(frozen=True)
class CarriedSheets:
    """What a day carries forward: the earlier Calibration Results Sheet, the earlier
    Survey Results Sheet, and the runs they came from (None: measured anew)."""

    prior: PriorSheet | None = None
    prior_run: PriorRun | None = None
    survey: SurveyResults | None = None
    survey_run: PriorRun | None = None

    def sheets_used(self, name: str) -> list[str]:
        """The sheet's "Sheet Used" (procedures.isu.sheets) plus the earlier sheets carried
        into it, by run uid."""
        used = sheets_used(name)
        if self.survey_run is not None and name.startswith(_CITE_SURVEY):
            used.append(self.survey_run.source("I-3"))
        if self.prior_run is not None and name.startswith(_CITE_PRIOR):
            used.append(self.prior_run.source("II-5"))
        return used

    def note(self) -> dict[str, Any]:
        """The journal start note's record of the carried sheets: the directories as given
        (what a resume compares) and the runs' uids."""
        out: dict[str, Any] = {}
        for key, run in (("prior", self.prior_run), ("survey", self.survey_run)):
            if run is not None:
                out[key] = str(run.path)
                out[f"{key}_run_uid"] = run.run_uid
        return out


def carried_sheets(cfg: StationConfig, prior: Path | None, survey: Path | None,
                   now: dt.datetime | None = None) -> CarriedSheets:
    """Load and check `--prior` and `--survey` (PriorRefused naming which and why)."""
    p_run, p_sheet = load_prior(prior, cfg, now) if prior is not None else (None, None)
    s_run, s_sheet = load_survey(survey, cfg, now) if survey is not None else (None, None)
    return CarriedSheets(p_sheet, p_run, s_sheet, s_run)
