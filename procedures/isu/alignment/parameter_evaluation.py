"""Alignment parameter evaluation (Part I, Section 3: Chart I-7, steps 1-5; Chart I-8 sheet).

Produces the "tape" of the posterior-mean estimator: M and b of Charts I-9 / I-10 for one
experiment's K, Delta t and inputs (``procedures.isu.alignment.parameter_sheet``). Steps carry
the tape's tag (``1/level``) when the sheet is run for several experiments in one run.
"""

from __future__ import annotations

from pathlib import Path

from procedures.isu.alignment.estimation import LevelParams
from procedures.isu.alignment.parameter_sheet import (
    AlignmentParameterSheet,
    Tape,
    make_tape,
    write_tape,
)
from procedures.runner import Run

CHART = "I-7"
TITLE = "Alignment parameter evaluation"


def reel_id(params: LevelParams, tag: str) -> str:
    return f"{tag}-K{params.K}-dt{params.dt:g}-eps{params.eps_t:g}"


def parameter_evaluation(run: Run, experiments: dict[str, tuple[LevelParams, str]],
                         tape_dir: Path | None = None) -> dict[str, Tape]:
    """Tick Chart I-7 for each experiment ``tag -> (params, prior_source)``; return tapes.

    Each tape is also written to ``tape_dir/<reel>.json`` when a directory is given.
    """
    tapes: dict[str, Tape] = {}
    with run.sheet(CHART, TITLE) as sheet:
        for tag, (params, prior) in experiments.items():
            with sheet.step(f"1/{tag}", "Verify input parameters are specified on the "
                            "Alignment Parameter Evaluation Sheet (Chart I-8)") as s:
                aps = AlignmentParameterSheet(
                    reel_id=reel_id(params, tag), prepared_by="procedures.isu.alignment",
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
                where = None
                if tape_dir is not None:  # recorded relative: records compare across dirs
                    tape_dir.mkdir(parents=True, exist_ok=True)
                    f = write_tape(tape, tape_dir / f"{aps.reel_id}.json")
                    where = f"{tape_dir.name}/{f.name}"
                run.save_sheet(f"alignment_parameters_{tag}", aps)
                s.reading = {"reel_id": aps.reel_id, "file": where}
            tapes[tag] = tape
    return tapes
