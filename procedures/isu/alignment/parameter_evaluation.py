"""Alignment parameter evaluation (Part I, Section 3: Chart I-7, steps 1-5; Chart I-8 sheet).

Produces the "tape" of the posterior-mean estimator: M and b of Charts I-9 / I-10 for one
experiment's K, Delta t and inputs (``procedures.isu.alignment.parameter_sheet``). Steps carry
the tape's tag (``1/level``) when the sheet is run for several experiments in one run.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from procedures.isu.alignment.estimation import LevelParams
from procedures.isu.alignment.parameter_sheet import (
    AlignmentParameterSheet,
    Tape,
    make_tape,
    write_tape,
)
from procedures.isu.alignment.tape_library import TapeLibrary
from procedures.runner import CheckSheetRun, Run

CHART = "I-7"
TITLE = "Alignment parameter evaluation"


def reel_id(params: LevelParams, tag: str) -> str:
    """The reel's identification: the experiment, and a digest of every Chart I-8 input so
    that two reels of one K and Delta t made from different inputs never share a name."""
    digest = hashlib.sha256(params.model_dump_json().encode("utf-8")).hexdigest()[:8]
    return f"{tag}-K{params.K}-dt{params.dt:g}-eps{params.eps_t:g}-{digest}"


def parameter_evaluation(run: Run, experiments: dict[str, tuple[LevelParams, str]],
                         tape_dir: Path | None = None, library: TapeLibrary | None = None
                         ) -> dict[str, Tape]:
    """Tick Chart I-7 for each experiment ``tag -> (params, prior_source)``; return tapes.

    With a ``library``, a reel made from the same Chart I-8 parameters is taken from it
    (step ``0/<tag>``, our addition: I-3 re-runs the evaluation only when a parameter
    changes) and steps 1-5 are not run; otherwise the tape is made and filed there. Each tape
    used is also written to ``tape_dir/<reel>.json`` when a directory is given, so the run's
    record holds every reel it used.
    """
    tapes: dict[str, Tape] = {}
    with run.sheet(CHART, TITLE) as sheet:
        for tag, (params, prior) in experiments.items():
            if library is not None:
                with sheet.step(f"0/{tag}", "(project addition) Look up the tape library "
                                "for a reel made from this experiment's Chart I-8 "
                                "parameters") as s:
                    found = library.find(params)
                    s.reading = {"library": library.root.name,
                                 "reel_id": found.tape.sheet.reel_id if found.tape else None,
                                 "why_not": found.why_not,
                                 "t1_offset_arcsec": found.t1_offset_arcsec}
                if found.tape is not None:
                    tapes[tag] = found.tape
                    run.save_sheet(f"alignment_parameters_{tag}", found.tape.sheet)
                    _keep(found.tape, tape_dir)
                    continue
            tapes[tag] = _evaluate(run, sheet, tag, params, prior, tape_dir, library)
    return tapes


def _keep(tape: Tape, tape_dir: Path | None) -> str | None:
    """The tape in the run's ``tape_dir`` (recorded relative: records compare across dirs)."""
    if tape_dir is None:
        return None
    tape_dir.mkdir(parents=True, exist_ok=True)
    f = write_tape(tape, tape_dir / f"{tape.sheet.reel_id}.json")
    return f"{tape_dir.name}/{f.name}"


def _evaluate(run: Run, sheet: CheckSheetRun, tag: str, params: LevelParams, prior: str,
              tape_dir: Path | None, library: TapeLibrary | None) -> Tape:
    """Steps 1-5 of Chart I-7 for one experiment."""
    with sheet.step(f"1/{tag}", "Verify input parameters are specified on the "
                    "Alignment Parameter Evaluation Sheet (Chart I-8)") as s:
        header = run.header_for(f"alignment_parameters_{tag}")
        aps = AlignmentParameterSheet(
            reel_id=reel_id(params, tag), prepared_by="procedures.isu.alignment",
            date=header.date if header is not None else "",
            prior_source=prior, params=params,
            comments="phi_n: accelerometer white noise and IEU string-count "
                     "quantization (procedures.isu.alignment.error_model)",
        )
        s.reading = {"reel_id": aps.reel_id, "K": params.K, "dt_s": params.dt,
                     "eps_t_s": params.eps_t, "g_tilde_mps2": params.g_tilde,
                     "sigma_g_mps2": params.sigma_g, "sigma_theta_rad":
                     params.sigma_theta, "T1": params.T1, "prior_source": prior}
    sheet.done(f"2/{tag}", "Load the parameter evaluation program",
               {"program": "procedures.isu.alignment.estimation",
                "charts": ["I-9", "I-10"]})
    sheet.done(f"3/{tag}", "Enter the input parameters from the sheet")
    with sheet.step(f"4/{tag}", "Initiate computations (Charts I-9, I-10)") as s:
        tape = make_tape(aps)
        s.reading = {"M_shape": [3, 3 * params.K], "b": tape.b,
                     "covariance": tape.covariance}
    with sheet.step(f"5/{tag}", "Mark the output reel; record its identification on "
                    "the sheet") as s:
        where = _keep(tape, tape_dir)
        filed = None
        if library is not None:
            library.file(tape)
            filed = library.root.name
        run.save_sheet(f"alignment_parameters_{tag}", aps)
        s.reading = {"reel_id": aps.reel_id, "file": where, "library": filed}
    return tape
