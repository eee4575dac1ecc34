"""What the alignment check-sheets of Part III work from, in one value.

Besides the station and the run, each alignment needs the laboratory's noise specification,
the calibration it applies (and the id the Alignment Results Sheet gives it), the survey,
the site, the operator's plan (K, Delta t, IEU period, options of III-2.2 and III-3.2), the
techniques to apply per method and the tapes of the posterior-mean techniques. These used to
travel as nine to eleven arguments from the command through ``run_alignments`` into each
procedure; ``AlignmentOptions`` carries them instead.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from procedures.isu.alignment.common import canonical_estimator
from procedures.isu.alignment.parameter_sheet import Tape
from procedures.isu.alignment.results_sheet import METHODS, AlignPlan
from procedures.isu.alignment.tape_library import TapeLibrary
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.sheets import CalibrationResults, SurveyResults
from procedures.isu.site import Site

# What `station day` runs after its calibration: every method, level and gyrocompass each
# processed by both techniques on the same record.
DAY_ESTIMATORS: Mapping[str, tuple[str, ...]] = MappingProxyType({
    "mirror": ("average",), "level": ("average", "posterior"),
    "gyrocompass": ("average", "hybrid")})


@dataclass(frozen=True)
class NominalAttitude:
    """The nominal T1 (T^EB at position 0) of the Alignment Parameter Evaluation Sheet, and
    which of the ways of I-3.1 gave it."""

    t1: np.ndarray
    source: str


@dataclass(frozen=True)
class AlignmentOptions:
    """The inputs and choices of the alignments of one run (see the module doc).

    ``estimators``: method -> techniques (default: ``DAY_ESTIMATORS``); ``tapes``: method ->
    the tape its posterior-mean technique uses (checked at Chart III-4 step 8 / III-8 step
    7; a missing one is produced by Chart I-7 in the run, into ``tape_dir``). ``survey``
    None: the run's own Survey Results Sheet, if it made one. ``site``: the Earth rate the
    gyrocompass checks against when there is no survey. ``library``: the tape library
    tapes are looked up in and filed to. ``nominal``: the nominal T1 of Chart I-8 (set by
    ``run_alignments`` from the plan's way of I-3.1; None: the resolvers').
    """

    noise: NoiseSpec
    calib: CalibrationResults
    survey: SurveyResults | None = None
    site: Site | None = None
    plan: AlignPlan = field(default_factory=AlignPlan)
    estimators: Mapping[str, tuple[str, ...]] = field(default_factory=lambda: DAY_ESTIMATORS)
    tapes: Mapping[str, Tape] = field(default_factory=lambda: MappingProxyType({}))
    tape_dir: Path | None = None
    calibration_id: str | None = None
    library: TapeLibrary | None = None
    nominal: NominalAttitude | None = None

    def __post_init__(self) -> None:
        unknown = sorted(set(self.estimators) - set(METHODS))
        if unknown:
            raise ValueError(f"estimators: unknown alignment method(s) {', '.join(unknown)}: "
                             "mirror, level or gyrocompass")
        unknown = sorted(set(self.tapes) - {"level", "gyrocompass"})
        if unknown:
            raise ValueError(f"tapes: no tape for method(s) {', '.join(unknown)}: only level "
                             "and gyrocompass use one")
        # canonical techniques, in the order asked, each once (frozen: set through object)
        est = {m: tuple(dict.fromkeys(canonical_estimator(m, e) for e in v))
               for m, v in self.estimators.items()}
        object.__setattr__(self, "estimators", MappingProxyType(est))
        object.__setattr__(self, "tapes", MappingProxyType(dict(self.tapes)))

    def nominal_t1(self) -> np.ndarray | None:
        return None if self.nominal is None else self.nominal.t1

    def techniques(self, method: str) -> tuple[str, ...]:
        """The techniques (canonical: ``canonical_estimator``) applied to ``method``'s record."""
        return self.estimators.get(method, ())

    def tape_for(self, method: str, estimator: str) -> Tape | None:
        """The tape ``estimator`` uses on ``method``'s record (None for the simple average)."""
        return None if estimator == "average" else self.tapes.get(method)

    def needs_tape(self) -> tuple[str, ...]:
        """The methods whose posterior-mean technique is asked for without a tape."""
        return tuple(m for m in ("level", "gyrocompass")
                     if any(e != "average" for e in self.techniques(m))
                     and m not in self.tapes)
