"""System survey (Chart I-2, steps 1-9; computations Charts I-4, I-5, I-6; results Chart I-3).

Position 0 is phi1 = 0, phi2 = 90, phi3 = 90, phi4 = 0 deg: the rotary axis up, and with a
nominal mounting B1 east, B2 north, B3 up. Autocollimator 1 on the east wall looks at
mirror 1 (normal B1) along azimuth 0, zenith 90; autocollimator 2 on the north wall looks at
mirror 2 (near B2) along azimuth 90, zenith 90. The true mounting T^BI is off identity by a
few tenths of a degree, more than the +/-0.5 deg field of view, so step 2 acquires each
mirror by a square spiral of aims ("trial and error", Flow Diagram 1) and centres on it.

Two corrections are the project's additions (Chart I-4 as printed takes T^FE = I, a table
base exactly level and aligned with the earth frame; the simulated laboratory's base is
tilted by about 15 arcsec and turned by about 25 arcsec in azimuth, and a survey that
ignores this puts those errors straight into T^BI and so into every calibration position):

* Level correction (``level_correction``): position 0 has the rotary axis up, the
  configuration the bubble levels read (corrections for phi1 and phi3, as in positions
  7-15). Their readings, taken interleaved with the autocollimator readings so that pier
  tilt and wobble are common to both, are applied to phi1^0 and phi3^0 before Chart I-4.
* Trunnion-axis azimuth (``base_azimuth``, step 5a): a turn of the base about the vertical
  is, at position 0, a turn about the rotary axis, invisible to the levels. Tilting the
  trunnion by 25 deg and reading both mirrors again shows the trunnion axis in the earth
  frame; its azimuth is added to phi2^0.

The Survey Results Sheet's phi^0 are the values entered into Chart I-4, i.e. corrected
(T^BI = ``survey_math.t_bi_from_survey(position0_deg, autocollimator_deg)`` holds on the
sheet); step 4's reading keeps the raw resolvers. Not removed: the non-orthogonality of the
table's gimbal junctions (a few arcsec each), which a single-position survey cannot see.
"""

from __future__ import annotations

import math
from functools import partial
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from procedures.isu import plausibility as pl
from procedures.isu import survey_math as sm
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.isu.readings import (
    axis_in_position,
    read_levels,
    read_mirror,
    resolvers,
    steady_resolvers,
)
from procedures.isu.sheets import SurveyResults
from procedures.isu.site import Site
from procedures.medians import median
from procedures.runner import Run
from station.drivers.isu import AutocollimatorDriver
from station.errors import CheckFailed, InstrumentRefused

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

CHART = "I-2"
TITLE = "System survey"
POSITION0_DEG = (0.0, 90.0, 90.0, 0.0)  # phi1..phi4
NOMINAL_AIM_DEG = {1: (0.0, 90.0), 2: (90.0, 90.0)}  # autocollimator k -> (azimuth, zenith)
SEARCH_STEP_DEG = 0.45  # a square grid of this pitch is covered by a 0.5 deg-radius field
SEARCH_RADIUS_DEG = 3.0  # half-width of the searched square around the nominal aim
N_READINGS = 60  # readings per mirror, alternating (1 min: also spans one pier-wobble period)
POSITION_TOLERANCE_ARCSEC = 10.0  # resolvers at position 0 within this of the command
TRUNNION_TILT_DEG = 25.0  # step 5a: mirror 2 rises to zenith ~65 deg (mount range 60-120)
TRUNNION_CHECK_ARCSEC = 30.0  # optical turn vs resolvers (resolver error ~1 arcsec)
EARTH_RATE_DEG_HR = 15.041067  # sidereal, used only to check the site entries' units


def _wrap180(d: float) -> float:
    return (d + 180.0) % 360.0 - 180.0


def square_spiral(step_deg: float, radius_deg: float) -> list[tuple[float, float]]:
    """Offsets (across, along zenith) in degrees: the centre, then square rings outwards."""
    n = int(math.floor(radius_deg / step_deg + 1e-9))
    out = [(0.0, 0.0)]
    for k in range(1, n + 1):
        ring = []
        for i in range(-k, k + 1):  # top and bottom edges
            ring += [(i, k), (i, -k)]
        for j in range(-k + 1, k):  # left and right edges
            ring += [(-k, j), (k, j)]
        ring.sort(key=lambda p: (p[0] ** 2 + p[1] ** 2, math.atan2(p[1], p[0])))
        out += [(i * step_deg, j * step_deg) for i, j in ring]
    return out


def acquire(
    ac: AutocollimatorDriver,
    index: int,
    az0: float,
    zen0: float,
    step_deg: float = SEARCH_STEP_DEG,
    radius_deg: float = SEARCH_RADIUS_DEG,
) -> dict:
    """Find a mirror return around (az0, zen0) and centre the autocollimator on it.

    Raises Implausible (a failed check) naming the searched region when no aim gives a return.
    """
    tried = refused = 0
    last_refusal = ""
    for dx, dz in square_spiral(step_deg, radius_deg):
        zen = zen0 + dz
        az = az0 + dx / max(math.sin(math.radians(zen)), 1e-6)  # dx is an angle across the sky
        try:
            ac.aim(az % 360.0, zen)
        except InstrumentRefused as e:  # e.g. outside the mount's zenith range: skip the aim
            refused += 1
            last_refusal = e.detail
            continue
        tried += 1
        m = ac.measure()
        if m is None:
            continue
        ac.aim(m[0], m[1])  # centre the field on the return
        centred = ac.measure()
        if centred is None:
            raise pl.Implausible(
                pl.source_of(ac), f"return from mirror {index} at azimuth {m[0]:.4f}, zenith "
                f"{m[1]:.4f} deg lost on centring")
        return {
            "nominal_aim_deg": [az0, zen0],
            "aims_tried": tried,
            "aims_refused": refused,
            "found_at_offset_deg": [dx, dz],
            "aim_deg": [m[0], m[1]],
            "first_reading_deg": [centred[0], centred[1]],
        }
    why = f"; {refused} aims refused ({last_refusal})" if refused else ""
    raise pl.Implausible(
        pl.source_of(ac), f"mirror {index} not found: no return at {tried} aims within "
        f"+/-{radius_deg:g} deg of azimuth {az0:g}, zenith {zen0:g} deg{why}")


def read_mirrors(
    st: IsuDrivers,
    n: int,
    aims: dict[int, tuple[float, float]],
    levels: bool,
    noise: NoiseSpec | None = None,
) -> tuple[tuple[float, float, float, float], dict, tuple[float, float] | None]:
    """Mean (alpha1, theta1, alpha2, theta2) of ``n`` readings per mirror, their spread
    (arcsec) and, if ``levels``, the mean bubble-level corrections (arcsec).

    The two autocollimators are read alternately, each reading followed at once by a level
    reading, so the pier tilt and wobble during the readings are common to both mirrors
    and to the level corrections. Azimuths are unwrapped around ``aims`` (0/360 deg).

    Nothing is averaged blindly: every reading must lie in its instrument's range and
    agree with the median of its repetitions within ``K_READING`` times the scatter the
    lab's specification predicts (reading noise and the pier's tilt over the readings); an
    outlier is read again (``plausibility.AgreeingReadings``: bounded, recorded in the
    enclosing ``rereads()`` block) and the step stops naming the instrument if the
    readings cannot be brought into agreement.
    """
    noise = noise or NoiseSpec.model_validate({})

    def mirror(k: int, _: int | None = None) -> list[float]:
        az, zen = read_mirror(st, k)
        az0 = aims[k][0]
        return [az0 + _wrap180(az - az0), zen]

    def level(_: int | None = None) -> list[float]:
        return list(read_levels(st))

    got = {k: pl.AgreeingReadings(st.autocollimators[k], f"mirror {k} azimuth and zenith",
                                  0.0, partial(mirror, k)) for k in (1, 2)}
    lev = pl.AgreeingReadings(st.bubble_levels, "level corrections", 0.0, level)
    times: list[float] = []
    for _ in range(n):
        for k in (1, 2):
            got[k].add(mirror(k))
            times.append(st.clock.now())
            if levels:
                lev.add(level())
    for k in (1, 2):
        zen = float(median([v[1] for v in got[k].values]))
        got[k].sigma = pl.autocollimator_sigma_deg(noise, times, zen)
        got[k].settle()
    if levels:
        lev.sigma = pl.level_sigma_arcsec(noise, times)
        lev.settle()
    mean = {k: np.mean(np.array(v.values), axis=0) for k, v in got.items()}
    spread = {
        str(k): [float(x) for x in np.std(np.array(v.values), axis=0, ddof=1) * 3600.0]
        if n > 1
        else [0.0, 0.0]
        for k, v in got.items()
    }
    ac = (float(mean[1][0]), float(mean[1][1]), float(mean[2][0]), float(mean[2][1]))
    lev_mean: tuple[float, float] | None = None
    if levels:
        c1, c3 = np.mean(np.array(lev.values), axis=0)
        lev_mean = (float(c1), float(c3))
    return ac, spread, lev_mean


def _trunnion_axis(
    st: IsuDrivers,
    raw: tuple[float, float, float, float],
    ac0: tuple[float, float, float, float],
    n: int,
    search_step_deg: float,
    noise: NoiseSpec | None = None,
) -> dict:
    """Step 5a: the trunnion axis's azimuth from the mirrors at phi1 = 0 and phi1 = tilt.

    Chart I-4 takes T^FE = I; a base turned about the vertical by a few tens of arcsec would
    go straight into T^BI as a turn about the rotary axis (B3 at position 0), misplacing by
    that much every body vector with a B1 or B2 part (all positions but 5, 6, 11 and 12,
    and by about half of it in 14 and 15). Tilting the trunnion turns
    the table about F2 only, and the mirrors show that axis in the earth frame
    (``survey_math.trunnion_axis_azimuth``). Mirror 2 (near north) rises to zenith
    90 - tilt, inside the wall autocollimators' mount range.
    """
    t_a = sm.mirror_alignment(*ac0)
    st.table.move(1, raw[0] + TRUNNION_TILT_DEG)
    st.table.wait_still()
    phi1_b = axis_in_position(st, 1, raw[0] + TRUNNION_TILT_DEG)
    turn = sm.rotation_about((0.0, 1.0, 0.0), phi1_b - raw[0])  # about east: north rises
    aims = {}
    for k, (a, th) in ((1, ac0[0:2]), (2, ac0[2:4])):
        az, zen = sm.angles(turn @ sm.direction(a, th))
        acquire(st.autocollimators[k], k, az, zen, search_step_deg, 2 * search_step_deg)
        aims[k] = (az, zen)
    ac_b, spread, _ = read_mirrors(st, n, aims, levels=False, noise=noise)
    st.table.move(1, POSITION0_DEG[0])
    st.table.wait_still()
    for k, (az0, zen0) in NOMINAL_AIM_DEG.items():  # back on the position-0 returns
        st.autocollimators[k].aim(*(ac0[0:2] if k == 1 else ac0[2:4]))
        if st.autocollimators[k].measure() is None:
            raise pl.Implausible(pl.source_of(st.autocollimators[k]),
                                 f"mirror {k} not found again at position 0 (aim {az0}, {zen0})")
    axis = sm.trunnion_axis_azimuth(t_a, sm.mirror_alignment(*ac_b))
    d_opt = axis["angle_deg"] * 3600.0
    d_res = (phi1_b - raw[0]) * 3600.0
    if abs(d_opt - d_res) > TRUNNION_CHECK_ARCSEC:
        raise pl.Implausible(
            pl.source_of(st.table), f"axis 1 resolver turned {d_res:.1f} arcsec while the "
            f"mirrors (autocollimators 1 and 2) turned {d_opt:.1f} arcsec")
    return {
        "phi1_deg": [raw[0], phi1_b],
        "autocollimator_deg": list(ac_b),
        "spread_arcsec": spread,
        "turn_optical_minus_resolver_arcsec": d_opt - d_res,
        **axis,
    }


def _angle_arcsec(a: ArrayLike, b: ArrayLike) -> float:
    u, v = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return math.degrees(math.atan2(float(np.linalg.norm(np.cross(u, v))), float(u @ v))) * 3600.0


def _check_site(site: Site) -> tuple[float, float, float]:
    g, ws, wc = site.g, site.omega_sin_lambda, site.omega_cos_lambda
    if not 0.99 <= g <= 1.01:
        raise CheckFailed(f"g = {g} is not in g units (expected about 1)")
    w = math.hypot(ws, wc)
    if abs(w - EARTH_RATE_DEG_HR) > 0.01 * EARTH_RATE_DEG_HR:
        raise CheckFailed(
            f"omega^E sin/cos lambda give |omega^E| = {w:.4f}, not the Earth rate "
            f"{EARTH_RATE_DEG_HR} deg/hr: check units (deg/hr) and lambda (colatitude)"
        )
    return g, ws, wc


def system_survey(
    station: IsuDrivers,
    run: Run,
    site: Site,
    n_readings: int = N_READINGS,
    search_step_deg: float = SEARCH_STEP_DEG,
    search_radius_deg: float = SEARCH_RADIUS_DEG,
    level_correction: bool = True,
    base_azimuth: bool = True,
    noise: NoiseSpec | None = None,
) -> SurveyResults:
    """Tick Chart I-2 and return the Survey Results Sheet (Chart I-3).

    ``site``: the laboratory's site; step 3 enters its ``g`` (g units), ``omega_sin_lambda``
    and ``omega_cos_lambda`` (deg/hr; lambda is the colatitude in report 000, so these are the
    north and vertical Earth-rate parts).
    """
    st = station
    if n_readings < 1:
        raise ValueError("n_readings must be >= 1")
    with run.sheet(CHART, TITLE) as sheet:
        with sheet.step("1", "Verify the turn-on check-sheet (Chart I-1) is complete") as s:
            done = run.check_sheets.get("I-1")
            if done is None or "check_I-1" not in run.sheets:
                raise CheckFailed("turn-on (Chart I-1) has not been completed in this run")
            if not done.steps or not all(r.done for r in done.steps):
                raise CheckFailed("turn-on (Chart I-1) has unticked steps")
            s.reading = {"turn_on_steps": len(done.steps), "completed_at_s": done.steps[-1].t_sim}

        with sheet.step("2", "Set position 0 and align the autocollimators with the mirrors") as s:
            for axis, deg in enumerate(POSITION0_DEG, start=1):
                st.table.move(axis, deg)
            st.table.wait_still()
            pos = resolvers(st)
            off = [abs(_wrap180(p - c)) * 3600.0 for p, c in zip(pos, POSITION0_DEG, strict=True)]
            if max(off) > POSITION_TOLERANCE_ARCSEC:
                raise pl.Implausible(pl.source_of(st.table),
                                     f"at {pos} deg, not at position 0 {POSITION0_DEG}")
            t0 = st.clock.now()
            found = {}
            for k, (az0, zen0) in NOMINAL_AIM_DEG.items():
                found[str(k)] = acquire(
                    st.autocollimators[k], k, az0, zen0, search_step_deg, search_radius_deg
                )
            s.reading = {"position0_deg": list(pos), "search_s": st.clock.now() - t0, **found}

        with sheet.step("3", "Record current estimates of g, omega^E sin and cos lambda") as s:
            g, ws, wc = _check_site(site)
            s.reading = {"g": g, "omega_sin_lambda_deg_hr": ws, "omega_cos_lambda_deg_hr": wc}

        with sheet.step("4", "Record test table resolver settings phi1^0..phi4^0") as s, \
                pl.rereads() as rr:
            raw = steady_resolvers(st, first=pos)  # must repeat step 2's reading
            s.reading = pl.with_rereads({"resolvers_deg": list(raw)}, rr)

        text5 = "Record azimuth and zenith angles alpha1, theta1, alpha2, theta2"
        with sheet.step("5", text5) as s, pl.rereads() as rr:
            ac_deg, spread, lev = read_mirrors(st, n_readings, NOMINAL_AIM_DEG,
                                               level_correction, noise)
            c1, c3 = lev if lev is not None else (0.0, 0.0)
            s.reading = pl.with_rereads({
                "autocollimator_deg": list(ac_deg),
                "n_readings": n_readings,
                "spread_arcsec": spread,
                "level_corrections_arcsec": list(lev) if lev is not None else None,
            }, rr)

        dphi2 = 0.0
        if base_azimuth:
            text = (
                f"(project addition) Tilt the trunnion to phi1 = {TRUNNION_TILT_DEG:g} deg, "
                "read both mirrors, return to position 0: trunnion-axis azimuth"
            )
            with sheet.step("5a", text) as s, pl.rereads() as rr:
                s.reading = pl.with_rereads(
                    _trunnion_axis(st, raw, ac_deg, n_readings, search_step_deg, noise), rr)
                dphi2 = s.reading["azimuth_arcsec"] / 3600.0

        with sheet.step("6", "Enter the System Survey Program (Charts I-4, I-5, I-6)") as s:
            s.reading = {"program": "procedures.isu.survey_math", "charts": ["I-4", "I-5", "I-6"]}

        with sheet.step("7", "Enter the data of steps 4 and 5") as s:
            p1, p2, p3, p4 = raw
            # bubble-level corrections are what the axes would need to be level: the table
            # stands where a level table would read phi - correction (module docstring)
            # and a base turned by the trunnion-axis azimuth stands at phi2 + azimuth (step 5a)
            pos0 = (p1 - c1 / 3600.0, p2 + dphi2, p3 - c3 / 3600.0, p4)
            s.reading = {"position0_deg": list(pos0), "autocollimator_deg": list(ac_deg)}

        text8 = ("Compute T^BI, phi3^m, phi4^m and T^BRm columns 2 and 3 "
                 "(m = 1, 3, 5, 13, 14, 15)")
        with sheet.step("8", text8) as s:
            t_bi = sm.t_bi_from_survey(pos0, ac_deg)
            settings = sm.resolver_settings(t_bi)
            col2 = {m: sm.t_br_column2(t_bi, *settings[m]) for m in sm.SURVEYED_POSITIONS}
            col3 = {m: sm.t_br_column3(t_bi, *settings[m]) for m in sm.SURVEYED_POSITIONS}
            # check: each setting puts its body vector along R1 (first column of T^BRm)
            worst = max(
                _angle_arcsec(sm.POSITION_VECTORS[m], sm.t_br(t_bi, *settings[m])[:, 0])
                for m in sm.SURVEYED_POSITIONS
            )
            if worst > 0.01:
                raise CheckFailed(f"resolver settings miss their body vectors by {worst} arcsec")
            s.reading = {
                "t_bi": t_bi.tolist(),
                "settings_deg": {str(m): list(v) for m, v in settings.items()},
                "t_br_column2": {str(m): list(v) for m, v in col2.items()},
                "t_br_column3": {str(m): list(v) for m, v in col3.items()},
            }

        with sheet.step("9", "Record the results on the Survey Results Sheet (Chart I-3)") as s:
            results = SurveyResults(
                g=g,
                omega_sin_lambda_deg_hr=ws,
                omega_cos_lambda_deg_hr=wc,
                position0_deg=pos0,
                autocollimator_deg=ac_deg,
                t_bi=t_bi.tolist(),
                settings_deg={str(m): v for m, v in settings.items()},
                t_br_column2={str(m): v for m, v in col2.items()},
                t_br_column3={str(m): v for m, v in col3.items()},
            )
            run.save_sheet("survey_results", results)
            s.reading = {"sheet": "survey_results"}
    return results
