"""Pattern-calibration data acquisition on the dividing head (report 004, steps 1-13).

Check-sheet ESG-CAL carries the report's thirteen steps (numbers as printed; the words are
ours); ESG-DP sets up the data processor and ESG-PA checks pickoff 1 against the spindle
by coning. Where the report leaves the method open we chose one and say so in
docs/esg.md: the drift-cancelling offset (step 3) is found by measuring the east-west
drift and re-damping at the computed equilibrium; the equal-ratio search (step 4) moves
the axes by the nominal geometry from the three count ratios; steps 6-7 read pickoff 2 at
the first ratio, the second and the first again so that a steady drift cancels in the
bisection. Printed slips: step 6 refers to step 3 and step 7 to step 5; both mean the
step before (4 and 6).

Each part is a journaled block (``Run.block``) so that a resume over links does not repeat
hours of rotor time: ESG-DP, the mount check (step 1), the spinning-rotor set-up (steps 2-8
with ESG-PA), each tilt readjustment and each scan. A restarted served rack (another
session) has lost the processor's zero and the rotor's spin axis: ``RENEW`` repeats every
block but the mount check then.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import TypeVar, overload

import numpy as np

from procedures.esg import alignment
from procedures.esg import geometry as geo
from procedures.esg.cosine import CosineParams
from procedures.esg.mechanization import (
    Mechanization,
    NominalParams,
    nominal_colatitude,
    nominal_count_ratio,
)
from procedures.esg.readings import AGREE, Setting, read_setting
from procedures.esg.readout import pickoffs_from_mirrors
from procedures.esg.setup import extremity_setup
from procedures.runner import CheckSheetRun, Run
from station.drivers.esg import EsgDrivers
from station.errors import CheckFailed

T = TypeVar("T")

# blocks a new session of a served rack repeats (processor zero, rotor state)
RENEW = ("ESG-DP", "ESG-CAL.rotor", "ESG-CAL.tilt-*", "ESG-CAL.scan-*")
MIRROR_ANGLE_DEG = 89.0 + 56.0 / 60.0 + 5.0 / 3600.0  # measured between the two mirrors
# step 3's longest wait between its two drift readings (our design): a lab whose lines are
# noisy enough to need more stops at step 3 by name
MAX_DRIFT_WAIT_S = 3600.0


@dataclass(frozen=True)
class EsgPlan:
    """The laboratory's choices for one calibration (degrees, seconds, count ratio)."""

    latitude_deg: float  # the site's (the laboratory's params give it: sim/esg/rotor.py)
    design_inclination_deg: float = 56.0  # great circle at the equator (pattern drawing)
    # the drawing's pattern: "great_circle" (the report's rotor) or "cosine" (its K from
    # the drawing; docs/esg-options.md); the lines end at design_top_deg
    pattern_kind: str = "great_circle"
    design_cosine_k: float = 0.0
    design_top_deg: float = 43.0
    mirror_angle_deg: float = MIRROR_ANGLE_DEG
    lines_per_setting: int = 5
    revolutions: int = 10
    spin_ready_rps: float = 248.0
    spinup_timeout_s: float = 3 * 3600.0
    damping_s: float = 900.0
    drift_wait_s: float = 600.0
    drift_tolerance_deg_hr: float = 0.1
    offset_iterations: int = 4
    equal_tolerance: float = 3e-5  # count-ratio spread accepted in step 4 (at least)
    equal_iterations: int = 6
    search_tolerance: float = 3e-6  # count ratio, about 1 arcsec at 55 deg
    search_iterations: int = 6
    local_slope_step_deg: float = 0.05  # step 7's readings either side of the equator
    coning_positions: int = 8
    mount_coning_limit_arcsec: float = 3.0
    pickoff_coning_limit_arcsec: float = 15.0
    fine_step_arcmin: float = 10.0
    fine_span_deg: float = 1.0
    scan_end_deg: int = 46  # last spindle offset from the equator inside the pattern
    move_timeout_s: float = 300.0
    electric_drift_spec_deg_hr: float = 0.2  # a priori bound used in the drift-error budget
    # the lab's line-to-line count-ratio scatter by its specification (pickoff jitter and
    # spin speed; the laboratory sets it): the agreement of a setting's lines and step 4's
    # spread are judged against it where it is larger than the report's figures suppose
    line_scatter_spec: float = 9e-6
    # ESG-DPX after step 2: lamps, discriminator and delay set up at the pattern extremity
    # (False: the processor's preset discriminator and delay, lamps as delivered)
    extremity_setup: bool = True
    # the data processor's counters: 2 as the report's (pickoffs read two at a time), 3 for
    # the simultaneous three-pickoff acquisition (docs/esg-options.md)
    counters: int = 2
    # step 1 and ESG-PA: a coning beyond its limit is adjusted (mount shimmed, pickoff 1
    # translated; up to alignment_iterations times) instead of stopping the run
    adjust_alignment: bool = False
    alignment_iterations: int = 3
    # sheet ESG-PA2 before step 1: the case remounted with mirror 2 along the spindle and
    # pickoff 2 adjusted the same way, then mounted back; after step 3 pickoff 3's tilt
    # towards mirror 1 measured and translated out (implies adjust_alignment)
    remount_alignment: bool = False
    # with the remount: pickoff 3's tilt towards mirror 2 too, in a second remount after
    # step 3 (procedures.esg.pickoff3_mirror2; implies remount_alignment)
    pickoff3_mirror2: bool = False
    # a scan point whose count ratio is this far from the drawing's at the scan's nominal
    # colatitude is a mis-gated count (the logic gate meeting another line near a cosine
    # pattern's extremity): the scan ends there (docs/esg-options.md)
    scan_gate_tolerance: float = 0.02

    @property
    def agree_tolerance(self) -> float:
        """A setting's lines agree within this (readings.AGREE, 5.5 line sigmas at least)."""
        return max(AGREE, 5.5 * self.line_scatter_spec)

    @property
    def equal_spread(self) -> float:
        """Step 4's accepted spread: equal_tolerance, or 7 sigmas of a setting's mean."""
        return max(self.equal_tolerance, 7.0 * self.setting_sigma)

    @property
    def setting_sigma(self) -> float:
        """The specified scatter of a setting's mean count ratio."""
        return self.line_scatter_spec / math.sqrt(self.lines_per_setting)

    @property
    def drift_wait(self) -> float:
        """Step 3's time between its two readings: drift_wait_s, or long enough that three
        sigmas of the measured rate (two settings' difference on the drawing's equator
        slope) are half the tolerance, up to MAX_DRIFT_WAIT_S (a noisy lab measures the
        drift longer, as it would by hand; the report gives no figure)."""
        rate_per_s = math.sqrt(2.0) * self.setting_sigma / abs(plan_slope_per_deg(90.0, self))
        need = 6.0 * rate_per_s * 3600.0 / self.drift_tolerance_deg_hr
        return max(self.drift_wait_s, min(need, MAX_DRIFT_WAIT_S))

    @property
    def tilt_probe_deg(self) -> float:
        """The tilt step that measures pickoff 1's slope (steps 8, 10-12): 0.02 deg, or
        enough for the ratio change to be 15 settings' sigmas on the drawing's slope."""
        return max(0.02, 15.0 * self.setting_sigma / abs(plan_slope_per_deg(90.0, self)))

    @property
    def tilt_miss_limit(self) -> float:
        """How far from the equator's ratio pickoff 1 may stay after the tilts: six
        settings' sigmas (or the search tolerance)."""
        return max(self.search_tolerance, 6.0 * self.setting_sigma)

    @property
    def adjusting(self) -> bool:
        """Shims and translations made (the remount's set-up needs the shims)."""
        return self.adjust_alignment or self.remounting

    @property
    def remounting(self) -> bool:
        """Sheet ESG-PA2 and pickoff 3's step after step 3 made."""
        return self.remount_alignment or self.pickoff3_mirror2


# ---------------------------------------------------------------- design mechanization
def design_params(inclination_deg: float) -> NominalParams:
    """The drawing's great circle: b = sin i, c = cos i, no edge offset (eq. 9)."""
    i = math.radians(inclination_deg)
    return NominalParams(math.sin(i), math.cos(i), 0.0)


def design_colatitude_deg(cr: float, inclination_deg: float) -> float:
    """Colatitude from a count ratio for the drawing's great circle (eq. 9: d = 0)."""
    return float(nominal_colatitude(cr, design_params(inclination_deg)))


def design_slope_per_deg(theta_deg: float, inclination_deg: float) -> float:
    """d(CR)/d(theta) of the drawing's pattern at a colatitude (numerical, per degree)."""
    p, h = design_params(inclination_deg), 0.01
    return float(nominal_count_ratio(theta_deg + h, p)
                 - nominal_count_ratio(theta_deg - h, p)) / (2 * h)


def drawing(plan: EsgPlan) -> Mechanization:
    """The drawing's mechanization of the plan's pattern (no offsets)."""
    if plan.pattern_kind == "cosine":
        return CosineParams(plan.design_cosine_k, 0.0)
    return design_params(plan.design_inclination_deg)


def plan_colatitude_deg(cr: float, plan: EsgPlan) -> float:
    """Colatitude from a count ratio by the drawing's pattern."""
    return float(nominal_colatitude(cr, drawing(plan)))


def plan_slope_per_deg(theta_deg: float, plan: EsgPlan) -> float:
    """d(CR)/d(theta) of the drawing's pattern at a colatitude (numerical, per degree)."""
    p, h = drawing(plan), 0.01
    return float(nominal_count_ratio(theta_deg + h, p)
                 - nominal_count_ratio(theta_deg - h, p)) / (2 * h)


def equal_ratio_direction(mirror_angle_deg: float) -> np.ndarray:
    """Spin direction in the case at equal angles to the three pickoffs (p1 = m1, p2 = m2
    in the c1-c2 plane at the measured mirror angle, p3 across both)."""
    return geo.unit(np.linalg.solve(pickoffs_from_mirrors(mirror_angle_deg), np.ones(3)))


# ---------------------------------------------------------------- acquisition record
@dataclass
class Baseline:
    """Pickoff 2 at the equator's count ratio before a scan and back at it after."""

    gamma_deg: float
    start: Setting
    end: Setting


@dataclass
class ScanPoint:
    scan: str  # "9", "10+", "10-", "11+", ...
    increment_deg: float  # 1/6, 5, 2 or 1
    offset_deg: float  # signed spindle offset from the scan's baseline, towards the side
    gamma_deg: float
    setting: Setting


@dataclass
class Scan:
    name: str
    side: int  # +1: towards the first hemisphere's equal point (colatitude below 90)
    increment_deg: float
    baseline: Baseline
    points: list[ScanPoint] = field(default_factory=list)


@dataclass
class Acquisition:
    """Everything the reduction needs, as the laboratory measured it."""

    t_zero_s: float = 0.0  # clock time of the processor's TZERO
    cr_a: float = 0.0  # equal-ratio count ratio, first hemisphere (colatitude theta*)
    cr_b: float = 0.0  # second hemisphere (180 - theta*)
    theta_star_deg: float = 0.0
    gamma_a_deg: float = 0.0
    gamma_b_deg: float = 0.0
    cr_eq: float = 0.0
    gamma_eq_deg: float = 0.0
    # d(CR)/d(spindle angle) measured at the equal-ratio tracks (step 6's secants) and at
    # the equator's track (step 7), per degree; 0.0: not measured (a journal before them)
    slope_a_per_deg: float = 0.0
    slope_b_per_deg: float = 0.0
    slope_eq_per_deg: float = 0.0
    colatitude_sign: int = 1  # +1: pickoff-2 colatitude grows with the spindle angle
    # step 7's time from step 6's second ratio over step 6's span between its two readings
    # of the first: the lever of the drift about the spindle measured there (0.0: not
    # recorded, a journal before it)
    equator_rate_lever: float = 0.0
    unbalance_k_deg_hr: float = 0.0
    residual_drift_deg_hr: float = 0.0
    mount_coning_arcsec: float = 0.0
    pickoff_coning_arcsec: float = 0.0
    scans: list[Scan] = field(default_factory=list)

    def state(self) -> dict:
        """The scalar results so far (a block's journal form; scans are kept apart)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "scans"}

    def set_state(self, d: dict) -> None:
        for k, v in d.items():
            setattr(self, k, v)


def scan_record(scan: Scan) -> dict:
    """A scan in its journal form."""
    b = scan.baseline
    return {"name": scan.name, "side": scan.side, "increment_deg": scan.increment_deg,
            "baseline": {"gamma_deg": b.gamma_deg, "start": b.start.reading(),
                         "end": b.end.reading()},
            "points": [{"scan": q.scan, "increment_deg": q.increment_deg,
                        "offset_deg": q.offset_deg, "gamma_deg": q.gamma_deg,
                        "setting": q.setting.reading()} for q in scan.points]}


def scan_from_record(d: dict) -> Scan:
    b = d["baseline"]
    base = Baseline(b["gamma_deg"], Setting.from_reading(b["start"]),
                    Setting.from_reading(b["end"]))
    return Scan(d["name"], d["side"], d["increment_deg"], base,
                [ScanPoint(q["scan"], q["increment_deg"], q["offset_deg"], q["gamma_deg"],
                           Setting.from_reading(q["setting"])) for q in d["points"]])


# ---------------------------------------------------------------- small operations
def _move_table(st: EsgDrivers, plan: EsgPlan, az: float | None = None,
                tilt: float | None = None) -> None:
    if az is not None:
        st.turntable.azimuth(az)
        st.turntable.wait_hold(plan.move_timeout_s)
    if tilt is not None:
        st.turntable.tilt(tilt)
        st.turntable.wait_hold(plan.move_timeout_s)


def _move_head(st: EsgDrivers, plan: EsgPlan, gamma: float) -> float:
    """Spindle to ``gamma`` (any real angle); the scale reading, unwrapped near gamma."""
    st.head.set(gamma % 360.0)
    st.head.wait_hold(plan.move_timeout_s)
    r = st.head.reading()
    return r + 360.0 * round((gamma - r) / 360.0)


def _read(st: EsgDrivers, plan: EsgPlan, pickoffs: tuple[int, ...]) -> Setting:
    return read_setting(st.processor, pickoffs, plan.lines_per_setting,
                        agree=plan.agree_tolerance)


def _scan_pickoffs(plan: EsgPlan) -> tuple[int, ...]:
    """Pickoff 2 (the scanned one) and pickoff 1, and pickoff 3 too with three counters."""
    return (2, 1, 3) if plan.counters >= 3 else (2, 1)


def _read_three(st: EsgDrivers, plan: EsgPlan) -> dict[int, float | None]:
    """The three count ratios: one setting on a three-counter processor; else pickoffs 1
    and 2, then 3 and 2 (pickoff 2's mean of the two)."""
    if plan.counters >= 3:
        r = _read(st, plan, (1, 2, 3))
        return {p: r.cr[p] for p in (1, 2, 3)}
    a = _read(st, plan, (1, 2))
    b = _read(st, plan, (3, 2))
    out = {1: a.cr[1], 3: b.cr[3]}
    p2 = [v for v in (a.cr[2], b.cr[2]) if v is not None]
    out[2] = sum(p2) / len(p2) if p2 else None
    return out


def _on_pattern(cr: dict[int, float | None], problem: str) -> dict[int, float]:
    """The count ratios when every pickoff is on the pattern; else a failed check."""
    on = {p: v for p, v in cr.items() if v is not None}
    if len(on) < len(cr):
        raise CheckFailed(problem)
    return on


def _settings(st: EsgDrivers) -> tuple[float, float, float]:
    az, tilt = st.turntable.readings()
    return az, tilt, st.head.reading()


def _spin_axis_lab(st: EsgDrivers, plan: EsgPlan, cr: dict[int, float]) -> np.ndarray:
    """The spin axis in the lab from three count ratios by the drawing's pattern and the
    nominal geometry (good to a few arcmin: enough to point the axes)."""
    alpha = np.array([math.cos(math.radians(plan_colatitude_deg(cr[i], plan)))
                      for i in (1, 2, 3)])
    s_case = geo.unit(np.linalg.solve(pickoffs_from_mirrors(plan.mirror_angle_deg), alpha))
    return geo.r_lc(*_settings(st)) @ s_case


def _move_all(st: EsgDrivers, plan: EsgPlan, az: float, tilt: float, gamma: float) -> None:
    _move_table(st, plan, az=az, tilt=tilt)
    _move_head(st, plan, gamma)


def _damp(st: EsgDrivers, plan: EsgPlan) -> None:
    st.console.damping(True)
    st.clock.sleep(plan.damping_s)
    st.console.damping(False)


def wait_speed(st: EsgDrivers, plan: EsgPlan, above: bool, rps: float) -> None:
    """Poll the console each minute until the rotor is above (or at or below) ``rps``."""
    t_end = st.clock.now() + plan.spinup_timeout_s
    while (st.console.speed() < rps) if above else (st.console.speed() > rps):
        if st.clock.now() > t_end:
            raise CheckFailed(f"rotor {'below' if above else 'above'} {rps:g} rps after "
                              f"{plan.spinup_timeout_s:g} s")
        st.clock.sleep(60.0)


def brake(st: EsgDrivers, plan: EsgPlan) -> None:
    """Spin off until the rotor is at rest; the spindle back to 0 (to mount the case)."""
    st.console.spin_off()
    wait_speed(st, plan, False, 0.0)
    _move_head(st, plan, 0.0)


@overload
def spin_up_damped(st: EsgDrivers, plan: EsgPlan) -> None: ...


@overload
def spin_up_damped(st: EsgDrivers, plan: EsgPlan, at_speed: Callable[[], T]) -> T: ...


def spin_up_damped(st: EsgDrivers, plan: EsgPlan, at_speed: Callable[[], T] | None = None
                   ) -> T | None:
    """Spin up with the damping coil on; at operating speed ``at_speed`` (the set-up's
    moves there), then damped for ``damping_s`` and the damping off; ``at_speed``'s value."""
    st.console.damping(True)
    st.console.spin_up()
    wait_speed(st, plan, True, plan.spin_ready_rps)
    value = at_speed() if at_speed is not None else None
    st.clock.sleep(plan.damping_s)
    st.console.damping(False)
    return value


# ---------------------------------------------------------------- sheets
def processor_setup(st: EsgDrivers, run: Run, plan: EsgPlan) -> dict:
    with run.sheet("ESG-DP", "Data processor adjustments") as sh:
        with sh.step("DP.1", "clock to zero; sum over ten revolutions; run number 1; HIT "
                     "threshold 1.5 V (pulses are about 2.1 V)") as s:
            t_zero = st.clock.now()  # the processor zeroes its clock on receipt
            st.processor.time_zero()
            st.processor.revolutions(plan.revolutions)
            st.processor.run_number(1)
            st.processor.threshold(1.5)
            s.reading = {"t_zero_s": t_zero}
        with sh.step("DP.2", "pulse-width discriminator and logic-line delay gate") as s:
            s.reading = st.processor.settings()
    return {"t_zero_s": sh.sheet.steps[0].reading["t_zero_s"]}


def _mirror_coning(st: EsgDrivers, plan: EsgPlan) -> dict:
    """One spindle turn in the theodolite: readings and mirror 1's coning radius."""
    n = plan.coning_positions
    g = [360.0 * k / n for k in range(n)]
    xy = []
    for gamma in g:
        _move_head(st, plan, gamma)
        xy.append(st.theodolite.read())
    _move_head(st, plan, 0.0)
    x = np.array([p[0] for p in xy])
    y = np.array([p[1] for p in xy])
    # a circle about the spindle: first harmonic of x and y over the turn
    gr = np.radians(g)
    rx = 2.0 / n * math.hypot(float(x @ np.cos(gr)), float(x @ np.sin(gr)))
    ry = 2.0 / n * math.hypot(float(y @ np.cos(gr)), float(y @ np.sin(gr)))
    return {"spindle_deg": g, "theodolite_arcsec": [list(p) for p in xy],
            "coning_radius_arcsec": 0.5 * (rx + ry),
            "limit_arcsec": plan.mount_coning_limit_arcsec}


def mount_check(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun) -> float:
    """Step 1: coning of mirror 1 about the spindle seen in the theodolite; with
    ``adjust_alignment`` the mount is shimmed and the coning measured again until it is
    within the limit (procedures.esg.alignment)."""
    limit = plan.mount_coning_limit_arcsec
    with sh.step("1", "mirror 1 along the spindle: theodolite readings over one spindle "
                 "turn; coning radius") as s:
        turn = _mirror_coning(st, plan)
        s.reading = turn
        if turn["coning_radius_arcsec"] > limit and not plan.adjusting:
            raise CheckFailed(f"mirror coning {turn['coning_radius_arcsec']:.1f} arcsec "
                              f"exceeds {limit:g}: re-shim the mount")
    return shim_to_limit(st, plan, sh, turn, "1")


def shim_to_limit(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, turn: dict,
                  prefix: str) -> float:
    """Steps ``<prefix>.shim-k``: the mount shimmed until the mirror along the spindle
    cones within the limit; its last coning radius."""
    limit = plan.mount_coning_limit_arcsec
    for k in range(1, plan.alignment_iterations + 1):
        if turn["coning_radius_arcsec"] <= limit:
            break
        with sh.step(f"{prefix}.shim-{k}", "mount shimmed by the coning's first harmonic "
                     "(spindle at 0); coning measured again") as s:
            x, y = alignment.shim_arcsec(turn["spindle_deg"], turn["theodolite_arcsec"])
            st.head.shim(x, y)
            turn = _mirror_coning(st, plan)
            s.reading = {"shim_arcsec": [x, y], **turn}
            if turn["coning_radius_arcsec"] > limit and k == plan.alignment_iterations:
                raise CheckFailed(f"mirror coning still {turn['coning_radius_arcsec']:.1f} "
                                  f"arcsec after {k} shims (limit {limit:g})")
    return float(turn["coning_radius_arcsec"])


def start_gyro(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun) -> None:
    """Step 2: damping-coil axis (the spindle) on the polar axis; spin up with damping."""
    with sh.step("2", "spindle on the Earth's polar axis; spin up to operating speed "
                 "with damping; damping off") as s:
        _move_table(st, plan, az=0.0, tilt=plan.latitude_deg)
        spin_up_damped(st, plan)
        s.reading = st.console.status()


def _east_drift(st: EsgDrivers, plan: EsgPlan, tilt: float) -> tuple[float, float]:
    """East-west drift of s (deg/hr) with s along the spindle (pickoffs 2 and 3 at the
    equator; pickoff 3 looks east at spindle angle 0, so its colatitude follows s east),
    and the mean spin period's count of its two readings (the speed it holds at)."""
    slope = plan_slope_per_deg(90.0, plan)
    a = _read(st, plan, (2, 3))
    st.clock.sleep(plan.drift_wait)
    b = _read(st, plan, (2, 3))
    if a.cr[3] is None or b.cr[3] is None:
        raise CheckFailed("pickoff 3 off the pattern while measuring drift")
    d_theta3 = (b.cr[3] - a.cr[3]) / slope  # deg
    return -d_theta3 / ((b.t_s - a.t_s) / 3600.0), 0.5 * (a.period_sum + b.period_sum)


def rundown_drift(k_deg_hr: float, period_then: float, period_now: float,
                  s_lab: np.ndarray) -> float:
    """The east-west drift the rotor's rundown alone leaves at an equilibrium set for
    ``k`` when the spin period's count was ``period_then``: the unbalance drift goes as
    1/spin (the torque stays, the momentum falls), so k has grown by period_now /
    period_then - 1 of itself, and its east rate is -k cos(elevation) (report 004 names
    rundown among the residual drift's causes; the interpolation of each scan takes it
    out, so step 3 does not try to null it)."""
    if k_deg_hr == 0.0 or period_then <= 0.0 or period_now <= 0.0:
        return 0.0
    grown = k_deg_hr * (period_now / period_then - 1.0)
    return -grown * math.cos(math.radians(geo.elevation_deg(s_lab)))


def cancel_drift(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun,
                 acq: Acquisition) -> None:
    """Step 3: offset s from the polar axis in the meridian plane until the east-west
    drift is cancelled by the Earth's rotation; re-measure and readjust. The drift left
    is judged without the part the rotor's rundown added since the last offset
    (``rundown_drift``): another offset would only chase it."""
    k = 0.0
    tilt = plan.latitude_deg
    period_set = 0.0  # the spin period's count when the offset was set for k
    for it in range(1, plan.offset_iterations + 1):
        with sh.step(f"3.{it}", "east-west drift with s along the spindle; offset the "
                     "spindle to the equilibrium and damp") as s:
            _move_head(st, plan, 0.0)
            rate, period = _east_drift(st, plan, tilt)
            s_lab = geo.from_az_el(0.0, tilt)
            rundown = rundown_drift(k, period_set, period, s_lab)
            done = abs(rate - rundown) <= plan.drift_tolerance_deg_hr
            if not done:
                k += geo.unbalance_k_from_east_drift(rate, s_lab)
                period_set = period
                tilt = geo.elevation_deg(geo.drift_equilibrium(plan.latitude_deg, k))
                _move_table(st, plan, tilt=tilt)
                _damp(st, plan)
            if not done and it == plan.offset_iterations:  # stop inside the step: named
                raise CheckFailed(f"east-west drift still {rate:+.3f} deg/hr after "
                                  f"{plan.offset_iterations} offsets ({rundown:+.3f} of it "
                                  f"the rundown's since the last offset; tolerance "
                                  f"{plan.drift_tolerance_deg_hr:g})")
            s.reading = {"east_drift_deg_hr": rate, "rundown_drift_deg_hr": rundown,
                         "unbalance_k_deg_hr": k, "tilt_deg": tilt,
                         "within_tolerance": done}
        acq.residual_drift_deg_hr = rate
        if done:
            break
    acq.unbalance_k_deg_hr = k


def equal_ratio_point(st: EsgDrivers, plan: EsgPlan, d_case: np.ndarray,
                      s_lab: np.ndarray) -> tuple[float, dict, np.ndarray]:
    """Step 4 for one hemisphere: move the axes until the three count ratios agree."""
    spread = math.inf
    for _ in range(plan.equal_iterations):
        a, e, g = geo.point_case(d_case, s_lab)
        _move_table(st, plan, az=a, tilt=e)
        _move_head(st, plan, g)
        read = _read_three(st, plan)
        cr = _on_pattern(read, f"a pickoff is off the pattern at the computed setting "
                               f"(count ratios {read}): the spin-axis estimate is far off")
        spread = max(cr.values()) - min(cr.values())
        s_lab = _spin_axis_lab(st, plan, cr)
        if spread <= plan.equal_spread:
            return sum(cr.values()) / 3.0, cr, s_lab
    raise CheckFailed(f"count ratios still {spread:.2e} apart after "
                      f"{plan.equal_iterations} adjustments")


def find_ratio(st: EsgDrivers, plan: EsgPlan, target: float, gamma: float,
               slope_per_deg: float | None = None) -> tuple[float, float, float]:
    """Spindle angle where pickoff 2 reads ``target``: (gamma, time, local slope).

    Secant steps on the spindle; the last two readings interpolate the angle, so the
    result does not depend on landing exactly on the ratio."""
    g0 = _move_head(st, plan, gamma)
    r0 = _read(st, plan, (2, 3))
    if slope_per_deg is None:
        g1 = _move_head(st, plan, gamma + 0.05)
        r1 = _read(st, plan, (2, 3))
        slope_per_deg = (r1.ratio(2) - r0.ratio(2)) / (g1 - g0)
        g0, r0 = g1, r1
    for _ in range(plan.search_iterations):
        step = (target - r0.ratio(2)) / slope_per_deg
        if abs(target - r0.ratio(2)) <= plan.search_tolerance:
            return g0 + step, r0.t_s, slope_per_deg
        g1 = _move_head(st, plan, g0 + step)
        r1 = _read(st, plan, (2, 3))
        if abs(g1 - g0) > 0.01:  # a shorter step's ratio change is mostly line noise
            slope_per_deg = (r1.ratio(2) - r0.ratio(2)) / (g1 - g0)
        g0, r0 = g1, r1
    return g0 + (target - r0.ratio(2)) / slope_per_deg, r0.t_s, slope_per_deg


def equal_ratio_points(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun, acq: Acquisition,
                       s_lab: np.ndarray) -> np.ndarray:
    """Step 4: equal count ratios on both rotor hemispheres."""
    d = equal_ratio_direction(plan.mirror_angle_deg)
    acq.theta_star_deg = math.degrees(math.acos(d[0]))
    with sh.step("4a", "case turned until the three count ratios agree (first "
                 "hemisphere)") as s:
        acq.cr_a, cr, s_lab = equal_ratio_point(st, plan, d, s_lab)
        s.reading = {"count_ratios": {str(k): v for k, v in cr.items()},
                     "mean": acq.cr_a, "settings_deg": list(_settings(st)),
                     "theta_star_deg": acq.theta_star_deg}
    with sh.step("4b", "the same on the opposite hemisphere") as s:
        acq.cr_b, cr, s_lab = equal_ratio_point(st, plan, -d, s_lab)
        s.reading = {"count_ratios": {str(k): v for k, v in cr.items()},
                     "mean": acq.cr_b, "settings_deg": list(_settings(st))}
    return s_lab


def equator(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun, acq: Acquisition,
            s_lab: np.ndarray) -> None:
    """Steps 5-7: spindle across the spin axis, the two equal ratios on pickoff 2, the
    equator by bisection."""
    th = math.radians(acq.theta_star_deg)
    with sh.step("5", "table and tilt: spindle across the spin axis, pickoff 2 near the "
                 "first equal-ratio colatitude") as s:
        a, e, g = geo.point_case([0.0, math.cos(th), math.sin(th)], s_lab)
        _move_table(st, plan, az=a, tilt=e)
        g = _move_head(st, plan, g)
        s.reading = {"settings_deg": [a, e, g]}
    with sh.step("6", "spindle readings where pickoff 2 reads the first, the second and "
                 "again the first equal ratio (step 4's means)") as s:
        ga1, ta1, slope_a = find_ratio(st, plan, acq.cr_a, g)
        # the second point is 180 - 2 theta* away, on the side where the ratio moves
        # towards the second ratio (falls on a great circle, rises on a cosine pattern)
        direction = 1.0 if slope_a * (acq.cr_b - acq.cr_a) > 0 else -1.0
        span = 180.0 - 2.0 * acq.theta_star_deg
        gb, tb, slope_b = find_ratio(st, plan, acq.cr_b, ga1 + direction * span)
        ga2, ta2, _ = find_ratio(st, plan, acq.cr_a, ga1, slope_a)
        acq.gamma_a_deg = 0.5 * (ga1 + ga2)
        acq.gamma_b_deg = gb
        acq.colatitude_sign = 1 if gb > acq.gamma_a_deg else -1
        acq.slope_a_per_deg, acq.slope_b_per_deg = slope_a, slope_b
        rate = (ga2 - ga1) / (ta2 - ta1)  # deg/s of spindle: drift about the spindle
        s.reading = {"gamma_a_deg": [ga1, ga2], "t_a_s": [ta1, ta2], "gamma_b_deg": gb,
                     "t_b_s": tb, "separation_deg": gb - acq.gamma_a_deg,
                     "drift_about_spindle_deg_hr": rate * 3600.0}
    with sh.step("7", "pickoff 2 midway: the equator's count ratio") as s:
        g_mid = 0.5 * (acq.gamma_a_deg + acq.gamma_b_deg)
        # the mid angle is the equator at time tb: each setting is aimed where the drift
        # has taken it by then, so only seconds of drift are carried through a slope (a
        # rough pattern's local slope can be half the drawing's: carrying a minute's drift
        # through the drawing's put the equator 11 arcsec off). The slope is this track's,
        # read first, so the equator's own setting follows a short move (the first setting
        # after the long move from step 6 read further from the truth in our trials)
        def aim() -> float:
            return g_mid + rate * (st.clock.now() - acq.t_zero_s - tb)
        slope_g = _local_slope(st, plan, aim(), rate)
        g_aim = aim()
        g_set = _move_head(st, plan, g_aim)
        r = _read(st, plan, _scan_pickoffs(plan))
        acq.cr_eq = r.ratio(2) - slope_g * ((g_set - g_mid) - rate * (r.t_s - tb))
        acq.gamma_eq_deg = g_mid + rate * (r.t_s - tb)
        acq.slope_eq_per_deg = slope_g
        acq.equator_rate_lever = (r.t_s - tb) / (ta2 - ta1)
        s.reading = {"gamma_mid_deg": g_mid, "gamma_aim_deg": g_aim, "cr_read": r.ratio(2),
                     "cr_eq": acq.cr_eq, "t_s": r.t_s,
                     "slope_eq_per_deg": acq.slope_eq_per_deg}


def _local_slope(st: EsgDrivers, plan: EsgPlan, gamma: float, rate: float) -> float:
    """d(CR)/d(spindle angle) on pickoff 2's track at ``gamma``: readings a little either
    side, the drift about the spindle (``rate``, deg/s) between them taken out.

    Beyond the report: step 9's slope is a fit over two degrees, while a rough pattern's
    count ratio bends on the scale of its roughness's correlation (0.1-0.4 deg of
    colatitude), so the small count-ratio differences at the equator (the baselines'
    drift, the search's residual) are carried through the slope of their own track."""
    d = plan.local_slope_step_deg
    g_lo = _move_head(st, plan, gamma - d)
    lo = _read(st, plan, (2, 3))
    g_hi = _move_head(st, plan, gamma + d)
    hi = _read(st, plan, (2, 3))
    return (hi.ratio(2) - lo.ratio(2)) / ((g_hi - g_lo) - rate * (hi.t_s - lo.t_s))


def tilt_to_equator(st: EsgDrivers, plan: EsgPlan, cr_eq: float) -> dict:
    """Pickoff 1 (along the spindle) to the equator's ratio with the tilt (steps 8, 10-12)."""
    _, tilt = st.turntable.readings()
    r0 = _read(st, plan, (1, 2))
    if r0.cr[1] is None:
        raise CheckFailed("pickoff 1 is off the pattern: the spindle is not across s")
    probe = plan.tilt_probe_deg
    st.turntable.tilt(round(tilt + probe, 4))
    st.turntable.wait_hold(plan.move_timeout_s)
    r1 = _read(st, plan, (1, 2))
    slope = (r1.ratio(1) - r0.cr[1]) / probe
    tilt += probe
    r = r1
    for _ in range(plan.search_iterations):
        if abs(r.ratio(1) - cr_eq) <= plan.search_tolerance:
            break
        tilt += (cr_eq - r.ratio(1)) / slope
        st.turntable.tilt(round(tilt, 4))
        st.turntable.wait_hold(plan.move_timeout_s)
        r = _read(st, plan, (1, 2))
    # beyond the report: a tilt that did not converge leaves the spin axis out of the
    # scan's plane, every colatitude of the scan wrong by far more than its sigma
    miss = abs(r.ratio(1) - cr_eq)
    if miss > plan.tilt_miss_limit:
        raise CheckFailed(f"pickoff 1 still reads {miss:.2e} from the equator's count ratio "
                          f"after {plan.search_iterations} tilts (at most "
                          f"{plan.tilt_miss_limit:.1e}): the spin axis is not across the "
                          "spindle")
    return {"tilt_deg": st.turntable.readings()[1], "cr_pickoff1": r.ratio(1)}


# what a coning turn keeps for the adjustment, not in its step's reading
TURN_INTERNAL = ("harmonic_cr", "partner_cr")


def _pickoff_coning(st: EsgDrivers, plan: EsgPlan, gamma0: float, pickoff: int = 1,
                    partner: int = 2) -> dict:
    """One spindle turn from ``gamma0`` (and back to it) reading ``pickoff`` (along the
    spindle) with ``partner``: its coning about the spindle from the count ratio's first
    harmonic, with the harmonic, its sigma and the partner's first count ratio."""
    slope = plan_slope_per_deg(90.0, plan)
    n = plan.coning_positions
    gs = [gamma0 + 360.0 * k / n for k in range(n + 1)]
    rows: list[tuple[float, float, float]] = []
    partner_cr = None
    for g in gs:
        gr = _move_head(st, plan, g)
        r = _read(st, plan, (pickoff, partner))
        cr = r.cr[pickoff]
        if cr is None:
            raise CheckFailed(f"pickoff {pickoff} left the pattern during the coning turn")
        partner_cr = r.cr[partner] if not rows else partner_cr
        rows.append((gr, r.t_s, cr))
    a = np.array([[1.0, math.cos(math.radians(g)), math.sin(math.radians(g)),
                   t - rows[0][1]] for g, t, _ in rows])
    y = np.array([c for _, _, c in rows])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    res = y - a @ coef
    cov = float(res @ res) / max(1, len(y) - 4) * np.linalg.inv(a.T @ a)
    amp = math.hypot(coef[1], coef[2])
    s_amp = math.sqrt(max(0.0, (coef[1] ** 2 * cov[1, 1] + coef[2] ** 2 * cov[2, 2])
                          / max(amp * amp, 1e-30)))
    return {"spindle_deg": [r[0] for r in rows], "t_s": [r[1] for r in rows],
            f"cr_pickoff{pickoff}": [r[2] for r in rows],
            "coning_arcsec": amp / abs(slope) * 3600.0,
            "sigma_arcsec": s_amp / abs(slope) * 3600.0,
            "limit_arcsec": plan.pickoff_coning_limit_arcsec,
            "harmonic_cr": [float(coef[1]), float(coef[2])], "partner_cr": partner_cr}


def pickoff_check(st: EsgDrivers, run: Run, plan: EsgPlan, acq: Acquisition) -> None:
    """ESG-PA: pickoff 1 against the spindle by coning, with s across the spindle; with
    ``adjust_alignment`` pickoff 1 is translated and its coning measured again until it is
    within the limit, and step 8's tilt is made again (procedures.esg.alignment)."""
    limit = plan.pickoff_coning_limit_arcsec
    with run.sheet("ESG-PA", "Pickoff alignment check by coning") as sh:
        with sh.step("PA.1", "pickoff 1 count ratio over one spindle turn (and back to "
                     "the start); first harmonic = coning of pickoff 1") as s:
            turn = _pickoff_coning(st, plan, acq.gamma_eq_deg)
            s.reading = {k: v for k, v in turn.items() if k not in TURN_INTERNAL}
            if not plan.adjusting:
                _refuse_pickoff_coning(turn, acq, limit)
        adjusted = 0
        while (plan.adjusting and turn["coning_arcsec"] > limit
               and adjusted < plan.alignment_iterations):
            adjusted += 1
            with sh.step(f"PA.translate-{adjusted}", "pickoff 1 translated in its fixture by "
                         "the coning's first harmonic; coning measured again") as s:
                h = turn["harmonic_cr"]
                a, b = alignment.pickoff_translation_arcsec(
                    h[0], h[1], plan_slope_per_deg(90.0, plan), acq.gamma_eq_deg,
                    acq.colatitude_sign)
                st.console.translate(1, a, b)
                turn = _pickoff_coning(st, plan, acq.gamma_eq_deg)
                s.reading = {"translation_arcsec": [a, b],
                             **{k: v for k, v in turn.items() if k not in TURN_INTERNAL}}
        if adjusted:
            with sh.step("PA.tilt", "tilt made again: pickoff 1 at the equator's ratio") as s:
                _move_head(st, plan, acq.gamma_eq_deg)
                s.reading = tilt_to_equator(st, plan, acq.cr_eq)
        _refuse_pickoff_coning(turn, acq, limit)


def _refuse_pickoff_coning(turn: dict, acq: Acquisition, limit: float) -> None:
    """Pickoff 1's coning recorded; CheckFailed if it exceeds the limit beyond the check's
    own uncertainty (3 sigma)."""
    acq.pickoff_coning_arcsec = turn["coning_arcsec"]
    refuse_coning(turn, limit, 1)


def refuse_coning(turn: dict, limit: float, pickoff: int) -> None:
    """CheckFailed if a pickoff's coning exceeds the limit beyond the check's own
    uncertainty (3 sigma)."""
    coning, sigma = turn["coning_arcsec"], turn["sigma_arcsec"]
    if coning - 3.0 * sigma > limit:
        raise CheckFailed(f"pickoff {pickoff} cones {coning:.1f} +- {sigma:.1f} arcsec "
                          f"about the spindle (limit {limit:g})")


def baseline_start(st: EsgDrivers, plan: EsgPlan, acq: Acquisition,
                   slope_per_deg: float) -> tuple[float, Setting]:
    """Pickoff 2 to the equator's ratio (one secant step from the last known angle): the
    spindle reading and the setting there."""
    g, _, _ = find_ratio(st, plan, acq.cr_eq, acq.gamma_eq_deg, slope_per_deg)
    acq.gamma_eq_deg = g
    g_set = _move_head(st, plan, g)
    return g_set, _read(st, plan, _scan_pickoffs(plan))


def run_scan(st: EsgDrivers, plan: EsgPlan, sh: CheckSheetRun, acq: Acquisition, name: str,
             side: int, increment: float, offsets: list[float], slope_per_deg: float) -> Scan:
    """One scan: baseline, the settings, back to the baseline's spindle angle."""
    with sh.step(f"{name}.0", "baseline: pickoff 2 at the equator's count ratio") as s:
        gamma0, start = baseline_start(st, plan, acq, slope_per_deg)
        s.reading = {"gamma_deg": gamma0, **start.reading()}
    points: list[ScanPoint] = []
    # spindle direction that lowers pickoff 2's colatitude for side +1
    sgn = -acq.colatitude_sign * side
    n_steps = len(offsets)
    for k, off in enumerate(offsets, start=1):
        with sh.step(f"{name}.{k:02d}", f"spindle {off:g} deg from the baseline") as s:
            g = _move_head(st, plan, gamma0 + sgn * off)
            r = _read(st, plan, _scan_pickoffs(plan))
            if r.cr[2] is None:
                raise CheckFailed(f"pickoff 2 off the pattern {off:g} deg from the "
                                  "equator")
            expected = float(nominal_count_ratio(90.0 - side * off, drawing(plan)))
            s.reading = {"gamma_deg": g, "offset_deg": side * off, **r.reading()}
            if abs(r.ratio(2) - expected) > plan.scan_gate_tolerance:
                s.reading.update(refused=f"count ratio {r.ratio(2):.5f} against the "
                                 f"drawing's {expected:.5f}: mis-gated, the scan ends here")
                n_steps = k
                break
            points.append(ScanPoint(name, increment, side * off, g, r))
    with sh.step(f"{name}.{n_steps + 1:02d}", "back to the baseline angle") as s:
        g = _move_head(st, plan, gamma0)
        end = _read(st, plan, _scan_pickoffs(plan))
        s.reading = {"gamma_deg": g, **end.reading()}
    scan = Scan(name, side, increment, Baseline(gamma0, start, end), points)
    acq.scans.append(scan)
    return scan


def _scan_offsets(start: float, stop: float, inc: float) -> list[float]:
    n = int(round((stop - start) / inc))
    return [round(start + inc * k, 6) for k in range(n + 1)]


def fine_slope(scan: Scan) -> float:
    """d(CR)/d(spindle offset towards side +) from the step-9 scan, drift removed."""
    b = scan.baseline
    t0, t1 = b.start.t_s, b.end.t_s
    drift = b.end.ratio(2) - b.start.ratio(2)
    x = np.array([p.offset_deg for p in scan.points])
    y = np.array([p.setting.ratio(2) - drift * (p.setting.t_s - t0) / (t1 - t0)
                  for p in scan.points])
    return float(np.polyfit(x, y, 2)[1])


def _scan_block(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun, acq: Acquisition,
                name: str, side: int, increment: float, offsets: list[float],
                slope_per_deg: float) -> Scan:
    """One scan as a journaled block: its settings and the equator angle it leaves."""
    def measure() -> dict:
        scan = run_scan(st, plan, sh, acq, name, side, increment, offsets, slope_per_deg)
        acq.scans.pop()  # added back by ``load``, the same for a fresh and a restored scan
        return {"scan": scan_record(scan), "gamma_eq_deg": acq.gamma_eq_deg}

    def load(d: dict) -> Scan:
        acq.gamma_eq_deg = d["gamma_eq_deg"]
        acq.scans.append(scan_from_record(d["scan"]))
        return acq.scans[-1]

    return run.block(f"ESG-CAL.scan-{name}", measure, load)


Pickoff3 = Callable[[EsgDrivers, EsgPlan, CheckSheetRun, Acquisition], dict]


def spin_and_offset(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun,
                    acq: Acquisition) -> None:
    """Steps 2 and 3 (with ESG-DPX after step 2): spin-up, s at the drift equilibrium."""
    start_gyro(st, run, plan, sh)
    if plan.extremity_setup:
        extremity_setup(st, run, plan.latitude_deg, plan.mirror_angle_deg,
                        lambda a, e, g: _move_all(st, plan, a, e, g), lambda: _damp(st, plan),
                        plan.design_top_deg)
    cancel_drift(st, run, plan, sh, acq)


def rotor_setup(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun,
                acq: Acquisition, pickoff3: Pickoff3 | None = None) -> None:
    """Steps 2-8 and ESG-PA: spin-up, drift offset, equal ratios, equator, tilt, lock;
    ``pickoff3`` after step 3 (pickoff 3's tilt towards mirror 1, with the remount)."""
    spin_and_offset(st, run, plan, sh, acq)
    if plan.remounting and pickoff3 is not None:
        pickoff3(st, plan, sh, acq)
    s_lab = geo.drift_equilibrium(plan.latitude_deg, acq.unbalance_k_deg_hr)
    s_lab = equal_ratio_points(st, run, plan, sh, acq, s_lab)
    equator(st, run, plan, sh, acq, s_lab)
    with sh.step("8", "tilt until pickoff 1 reads the equator's ratio; lock the table") as s:
        _move_head(st, plan, acq.gamma_eq_deg)
        s.reading = tilt_to_equator(st, plan, acq.cr_eq)
        st.turntable.lock()
    pickoff_check(st, run, plan, acq)


def calibration_scans(st: EsgDrivers, run: Run, plan: EsgPlan, sh: CheckSheetRun,
                      acq: Acquisition) -> None:
    """Steps 9-12 (step 8, the tilt and lock, is the end of ``rotor_setup``)."""
    # d(CR)/d(gamma) at the equator: d(CR)/d(theta) times d(theta)/d(gamma)
    slope_g = plan_slope_per_deg(90.0, plan) * acq.colatitude_sign
    inc9 = plan.fine_step_arcmin / 60.0
    n9 = int(round(plan.fine_span_deg / inc9))
    offs9 = [round(inc9 * k, 6) for k in range(-n9, n9 + 1) if k != 0]
    sc9 = _scan_block(st, run, plan, sh, acq, "9", 1, inc9, offs9, slope_g)
    slope_side = fine_slope(sc9)  # per degree towards side +
    slope_g = slope_side * (-acq.colatitude_sign)  # back to per degree of gamma
    end = plan.scan_end_deg
    for step, inc, first in (("10", 5.0, 5.0), ("11", 2.0, 30.0), ("12", 1.0, 40.0)):
        def tilt(step: str = step) -> None:
            with sh.step(f"{step}.tilt", "tilt readjusted: pickoff 1 at the equator's "
                         "ratio") as s:
                _move_head(st, plan, acq.gamma_eq_deg)
                s.reading = tilt_to_equator(st, plan, acq.cr_eq)
        run.block(f"ESG-CAL.tilt-{step}", tilt, lambda _: None)
        last = end - (end - first) % inc
        for side, tag in ((1, "+"), (-1, "-")):
            _scan_block(st, run, plan, sh, acq, f"{step}{tag}", side, inc,
                        _scan_offsets(first, last, inc), slope_g)


def acquire(st: EsgDrivers, run: Run, plan: EsgPlan,
            remount: Callable[[EsgDrivers, Run, EsgPlan], dict] | None = None,
            pickoff3: Pickoff3 | None = None) -> Acquisition:
    """Sheets ESG-DP, ESG-CAL (steps 1-13) and ESG-PA; returns the acquisition record.
    ``remount``: sheet ESG-PA2 before step 1 with ``plan.remount_alignment``
    (procedures.esg.remount.pickoff2_alignment, which uses this module's steps), and
    ``pickoff3`` after step 3 (procedures.esg.pickoff3.pickoff3_alignment)."""
    acq = Acquisition()
    acq.t_zero_s = run.block("ESG-DP", lambda: processor_setup(st, run, plan)["t_zero_s"],
                             float)
    if plan.remounting:
        if remount is None:
            raise ValueError("remount_alignment needs the ESG-PA2 sheet "
                             "(procedures.esg.remount.pickoff2_alignment)")
        run.block("ESG-PA2", lambda: remount(st, run, plan), dict)
    with run.sheet("ESG-CAL", "Pattern calibration data acquisition") as sh:
        acq.mount_coning_arcsec = run.block(
            "ESG-CAL.mount", lambda: mount_check(st, run, plan, sh), float)

        def rotor() -> dict:
            rotor_setup(st, run, plan, sh, acq, pickoff3)
            return acq.state()
        run.block("ESG-CAL.rotor", rotor, acq.set_state)
        calibration_scans(st, run, plan, sh, acq)
        with sh.step("13", "gyro shut down; data to reduction") as s:
            st.console.spin_off()
            s.reading = {"scans": len(acq.scans),
                         "settings": sum(len(x.points) + 2 for x in acq.scans)}
    return acq
