"""The strapdown ESG laboratory of report 004 on one simpy environment (integer ns).

A Leitz dividing head on a turntable with tilt carries the gyro case; a control console
spins, damps and monitors the rotor; the data processor times the pickoff pulses. The
interface is docs/esg.md. Nothing here schedules simpy events: every state is a
function of the time, moves and console commands take effect at computed times, and a
data line is computed in one vectorised call. All random draws come from
`sim.rng.stream(seed, "esg", ...)`.

Start state: rotor suspended and at rest, its axis on the damping-coil axis c1; damping
off; table at A = 0, E = 0; spindle at 0.

Magnitudes (defaults; the report's value where it gives one, else our choice and why):
  * site latitude 44.98 deg (Honeywell Aerospace Division, Minneapolis).
  * rotor: I = 114 g cm^2 (rotor no. 2, Niculoy plated); run to 250 rps (the report's
    operating speed, usable 200-500) by a linear ramp in 1800 s (our choice); rundown
    exponential with tau = 88 h, so 250 rps becomes about 244 rps after 2.15 h
    (Appendix A: period sums near 4.10e6 counts for ten revolutions). Below 10 rps the
    axis is held on c1; above, the spin coils' torque pulls it toward c1 while they drive
    (sim.esg.rotor), so a spin-up with damping on ends within about 0.2 deg of c1.
  * axial mass unbalance 11 dyne-cm (specified 0.2): drift k = 12.7 deg/h at 250 rps.
  * electric-torque drift: smooth field fixed in the case, 0.2 deg/h rms (our choice: a
    residual drift that makes the report's drift interpolation worthwhile).
  * damping toward c1 with a 60 s time constant (our choice; minutes, like a console
    damping loop).
  * pattern: great circle inclined 56 deg, lines ending at colatitude 43 deg (latitude 47),
    line width 0.060, logic line 0.030 with a 0.060 gap, all in inches on the 1-inch rotor;
    tool offset d0 0.0005 inch sd, logic offset 0.002 inch sd, smooth application error
    peak 150 micro-inch per edge, edge roughness 40 micro-inch rms with a 0.004-inch
    correlation length (the report's edge goal was 80 micro-inch peak to peak and its
    line resolution about 90; these flaws alone leave 7-8 arcsec rms after a 7th-order
    fit, and drift, scale and setting errors bring it toward the reported 11-14 arcsec).
  * case: mirrors at 89 deg 56 min 5 sec; pickoffs within 15 arcsec of their mirrors
    (coning tolerance); mounting residual coning 1 arcsec rms after shimming (the
    report shims to 3 arcsec or less: 3 arcsec is then a 1-in-8000 case).
  * head: scale error up to 1.5 arcsec (harmonics), 0.5 arcsec rms setting, slew 3 deg/s,
    settle 3 s. Turntable: 3 arcsec rms setting, slew 2 deg/s, settle 5 s.
    Theodolite: 0.5 arcsec rms per reading.
  * processor: pulses 2.1 V +-5 %, HIT threshold 1.5 V, 80 ns rms jitter per edge, arc marks
    0.02 per revolution per pickoff, discriminator 20 us, logic delay 241 us (see
    sim.esg.processor), 100 MHz clock with a 1e-9 sd fractional offset.
  * vacuum gauge: 5e-7 torr (the report's pump-down requirement).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import simpy

from sim.esg.case import CaseSpec, GyroCase, small_rotation
from sim.esg.mount import Mount, MountSpec, case_to_lab, spindle_axis
from sim.esg.pattern import Pattern, PatternSpec
from sim.esg.processor import (
    Channel,
    LineCounts,
    ProcessorSettings,
    SignalSpec,
    make_clock,
    measure_line,
)
from sim.esg.rotor import Rotor, RotorSpec
from sim.rng import stream
from sim.timebase import seconds
from sim.units import ARCSEC

MIN_RPS = 1.0  # below this the processor sees no usable pulses
_TIME_SLACK = 1e-9  # s


@dataclass(frozen=True)
class EsgParams:
    """Everything the ESG laboratory is made of, with the defaults listed in the module.

    Each part's defaults live in its own spec (the rotor's, site latitude included, in
    ``RotorSpec``); this holds the parts and the vacuum gauge's reading."""

    rotor: RotorSpec = field(default_factory=RotorSpec)
    pressure_torr: float = 5e-7
    pattern: PatternSpec = field(default_factory=PatternSpec)
    mount: MountSpec = field(default_factory=MountSpec)
    case: CaseSpec = field(default_factory=CaseSpec)
    signal: SignalSpec = field(default_factory=SignalSpec)
    # the data processor's time-interval counters: 2 as built (report 004: "A simultaneous
    # measurement of the three pickoffs was not possible"), 3 to read all three at once
    counters: int = 2

    @property
    def latitude_deg(self) -> float:
        """The laboratory's latitude (where the rotor feels the Earth's rate)."""
        return self.rotor.latitude_deg

    @property
    def spin_rps(self) -> float:
        """The console's operating spin speed."""
        return self.rotor.spin_rps


def _azimuth_about(s: np.ndarray, p: np.ndarray) -> float:
    """Azimuth of p about s from a reference fixed to the case (the axis least along s)."""
    ref = np.zeros(3)
    ref[int(np.argmin(np.abs(s)))] = 1.0
    e1 = ref - (ref @ s) * s
    e1 /= np.linalg.norm(e1)
    e2 = np.array([s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                   s[0] * e1[1] - s[1] * e1[0]])
    return math.atan2(float(p @ e2), float(p @ e1))


class EsgWorld:
    """Dividing head, turntable, gyro, console and data-processor physics (contract API)."""

    def __init__(self, seed: int, params: EsgParams | None = None,
                 env: simpy.Environment | None = None) -> None:
        self.seed = int(seed)
        self.p = params or EsgParams()
        self.env = env if env is not None else simpy.Environment()
        self.pattern = Pattern(self.p.pattern, self.seed)
        self.case = GyroCase(self.p.case, self.seed)
        self.mount = Mount(self.p.mount, self.seed, self.case.mounting)
        self.rotor = Rotor(self.p.rotor, self.seed, self.mount)
        self.clock = make_clock(self.seed, self.p.signal)
        sig = self.p.signal
        rng = stream(self.seed, "esg", "channels")
        self._heights = sig.pulse_height_v * (1.0 + rng.uniform(
            -sig.pulse_height_tol, sig.pulse_height_tol, 3))
        self._delays = 1e-9 * (sig.hit_delay_ns + rng.normal(0.0, sig.hit_delay_spread_ns, 3))
        self._phase0 = float(rng.uniform())
        # lamps as delivered: the pulses come out up to 25 % above the trimmed height until
        # the lamp currents are equalised ("Before data taking"); a stream of its own
        self._lamp_gain = stream(self.seed, "esg", "lamps").uniform(1.0, 1.25, 3)
        self._lamp_current = np.ones(3)  # fraction of the nominal lamp current
        self._shims = 0  # adjustments made so far (each draws its own error stream)
        self._translations = 0
        self._remounts = 0
        self._axis_case: dict[float, np.ndarray] = {}  # spin_axis_case at past instants

    @property
    def now(self) -> float:
        return seconds(self.env.now)

    def _past(self, t: float) -> float:
        if t > self.now + _TIME_SLACK or t < 0.0:
            raise ValueError(f"time {t} s is outside [0, now = {self.now} s]")
        return min(t, self.now) if t > self.now else t

    # ----- dividing head -----
    def head_move(self, gamma_deg: float) -> float:
        """Start a spindle move to the absolute scale angle; returns the arrival time (s)."""
        return self.mount.head_move(self.now, float(gamma_deg))

    def head_reading_deg(self) -> float:
        """The scale reading (the commanded angle once the head holds)."""
        return self.mount.head.reading_deg(self.now)

    def head_moving(self) -> bool:
        return self.mount.head.moving(self.now)

    # ----- turntable and tilt -----
    def table_move(self, azimuth_deg: float | None = None, tilt_deg: float | None = None
                   ) -> float:
        """Start a table move (either axis may be left alone); returns the arrival time (s)."""
        return self.mount.table_move(self.now, azimuth_deg, tilt_deg)

    def table_reading_deg(self) -> tuple[float, float]:
        return (self.mount.azimuth.reading_deg(self.now), self.mount.tilt.reading_deg(self.now))

    def table_moving(self) -> bool:
        return self.mount.moving_table(self.now)

    # ----- theodolite -----
    def theodolite_arcsec(self) -> tuple[float, float]:
        """Mirror-1 normal versus the spindle axis on two lab-fixed axes, arcsec, with noise."""
        a, e, _ = self.mount.angles(self.now)
        return self.case.theodolite(self.mount.matrix(self.now), a, e)

    # ----- alignment adjustments (report 004, "Mirror and Pickoff Alignment") -----
    def shim(self, x_arcsec: float, y_arcsec: float) -> None:
        """Re-shim the case on the spindle plate: the normal of the mirror along the
        spindle (mirror 1 unless remounted) moves by (x, y) arcsec
        on the theodolite's axes at the present table and spindle angles, within the
        shim's own error (CaseSpec), from now on."""
        spec, now = self.case.spec, self.now
        self._shims += 1
        rng = stream(self.seed, "esg", "shim", self._shims)
        want = np.array([x_arcsec, y_arcsec], float)
        got = (want * (1.0 + rng.normal(0.0, spec.shim_scale_sd, 2))
               + rng.normal(0.0, spec.shim_error_arcsec, 2)) * ARCSEC
        a, e, g = self.mount.angles(now)
        bare = case_to_lab(a, e, g)  # the spindle's rotation without the mounting
        u = spindle_axis(a, e)
        h = np.array([math.cos(a), -math.sin(a), 0.0])  # the theodolite's axes (GyroCase)
        v = np.cross(h, u)
        m1 = bare @ self.mount.mounting @ self.case.mirror(self.case.mirror_on_spindle)
        turn = small_rotation(np.cross(m1, got[0] * h + got[1] * v))
        mounting = bare.T @ turn @ bare @ self.mount.mounting
        self.mount.reshim(now, mounting)
        self.case.remount(mounting)

    def remount(self, mirror: int) -> None:
        """The case taken off the adapter plate and set back with mirror ``mirror`` (1 or
        2) along the spindle (report 004, "Mirror and Pickoff Alignment": the procedure
        repeated for the second pickoff), off by the remount error (CaseSpec) until
        shimmed, from now on; the rotor must be at rest (the instrument refuses else)."""
        if mirror not in (1, 2):
            raise ValueError(f"mirror must be 1 or 2: {mirror}")
        self._remounts += 1
        rng = stream(self.seed, "esg", "remount", self._remounts)
        mounting = self.case.mounting_for(mirror, rng)
        self.mount.reshim(self.now, mounting)
        self.case.remount(mounting, mirror)

    def translate_pickoff(self, pickoff: int, a_arcsec: float, b_arcsec: float) -> None:
        """Translate a pickoff in its fixture: its line of sight moves a arcsec along the
        next case axis and b along the one after (pickoff 1: c2, c3; 2: c3, c1; 3: c1,
        c2), within the fixture's own error (CaseSpec), from now on."""
        spec = self.case.spec
        self._translations += 1
        rng = stream(self.seed, "esg", "translate", self._translations)
        want = np.array([a_arcsec, b_arcsec], float)
        got = (want * (1.0 + rng.normal(0.0, spec.translate_scale_sd, 2))
               + rng.normal(0.0, spec.translate_error_arcsec, 2)) * ARCSEC
        axes = np.eye(3)[[pickoff % 3, (pickoff + 1) % 3]]
        self.case.translate(self.now, pickoff, got @ axes)

    # ----- console -----
    def spin_up(self) -> None:
        self.rotor.spin_up(self.now)

    def spin_off(self) -> None:
        self.rotor.spin_off(self.now)

    def set_damping(self, on: bool) -> None:
        self.rotor.set_damping(self.now, bool(on))

    def console_status(self) -> dict:
        now = self.now
        return {"suspended": True, "spin_rps": self.rotor.spin_rps(now),
                "damping": self.rotor.damping(now), "pressure_torr": self.p.pressure_torr}

    # ----- data processor -----
    def data_line(self, t: float, pickoff_a: int, pickoff_b: int, revolutions: int,
                  settings: ProcessorSettings, pickoff_c: int | None = None) -> LineCounts:
        """Counts for the `revolutions` revolutions ending at time t (t <= now); a third
        pickoff ``pickoff_c`` on a three-counter processor."""
        chosen = [pickoff_a, pickoff_b] + ([] if pickoff_c is None else [pickoff_c])
        if set(chosen) - {1, 2, 3} or len(set(chosen)) < len(chosen):
            raise ValueError(f"pickoffs must be distinct of 1..3: {chosen}")
        if int(revolutions) < 1:
            raise ValueError("revolutions must be >= 1")
        revolutions = int(revolutions)
        t = self._past(float(t))
        rps = self.rotor.spin_rps(t)
        if rps < MIN_RPS:
            return LineCounts({1: 0, 2: 0, 3: 0}, 0, 0, False)
        window = (revolutions + 3) / rps
        rps = max(self.rotor.spin_rps(t - 0.5 * window), MIN_RPS) if t > window else rps
        t0 = max(t - window, 0.0)
        s_end, s_start = self.spin_axis_case(t), self.spin_axis_case(t0)
        alpha = 2.0 * math.pi * ((self.rotor.profile.revolutions(t) + self._phase0) % 1.0)
        channels = []
        for i in chosen:
            p = self.case.pickoffs_at(t)[i - 1]
            th_end = math.acos(max(-1.0, min(1.0, float(p @ s_end))))
            th_start = math.acos(max(-1.0, min(1.0, float(p @ s_start))))
            view = (alpha + _azimuth_about(s_end, p)) % (2.0 * math.pi)
            channels.append(Channel(i, th_end, th_start, view, self.pulse_height_v(i),
                                    float(self._delays[i - 1])))
        return measure_line(self.pattern, self.p.signal, settings, self.seed, t, rps,
                            revolutions, channels, pickoff_a, self.clock)

    # ----- lamps and the processor's scope -----
    def set_lamp(self, pickoff: int, fraction: float) -> None:
        """Lamp current of a pickoff as a fraction of nominal (the pulse height follows)."""
        self._lamp_current[pickoff - 1] = float(fraction)

    def lamp(self, pickoff: int) -> float:
        return float(self._lamp_current[pickoff - 1])

    def pulse_height_v(self, pickoff: int) -> float:
        """Genuine pulse height of a pickoff at its present lamp current."""
        i = pickoff - 1
        return float(self._heights[i] * self._lamp_gain[i] * self._lamp_current[i])

    def scope(self, pickoff: int) -> dict | None:
        """What an oscilloscope on a pickoff's HIT output shows now: pulse height (V), the
        widths of the logic line and lines 1 and 2 (us) and the time from the logic line's
        trailing edge to line 1's (us); None when the pickoff sees no pattern."""
        t = self.now
        rps = self.rotor.spin_rps(t)
        th = float(self.true_colatitudes(t)[pickoff - 1])
        e = self.pattern.edges(np.array([th]))
        if rps < MIN_RPS or not bool(e.visible[0]):
            return None
        us = 1e6 / (2.0 * math.pi * rps)
        return {"height_v": self.pulse_height_v(pickoff),
                "widths_us": [float((e.logic_trail - e.logic_lead)[0] * us),
                              float((e.line1_trail - e.line1_lead)[0] * us),
                              float((e.line2_trail - e.line2_lead)[0] * us)],
                "logic_to_line_us": float((e.line1_trail - e.logic_trail)[0] * us)}

    # ----- truth -----
    def case_to_lab(self, t: float) -> np.ndarray:
        """R_LC at t (columns c1, c2, c3 in L)."""
        return self.mount.matrix(self._past(t))

    def spindle_axis_lab(self, t: float) -> np.ndarray:
        a, e, _ = self.mount.angles(self._past(t))
        return spindle_axis(a, e)

    def spin_axis_lab(self, t: float) -> np.ndarray:
        return self.rotor.axis_lab(self._past(t))

    def spin_axis_case(self, t: float) -> np.ndarray:
        """The spin axis in case axes at t. A time already past when first asked is kept:
        nothing done from now on changes it, and the lines and the truth ask again for the
        same instants (a calibration run: 5449 queries at 1553 instants)."""
        t = self._past(t)
        hit = self._axis_case.get(t)
        if hit is not None:
            return hit.copy()
        s = self.mount.matrix(t).T @ self.rotor.axis_lab(t)
        if t < self.now:
            self._axis_case[t] = s.copy()
        return s

    def true_colatitudes(self, t: float) -> np.ndarray:
        """Angles between each pickoff's line of sight and the spin axis, rad (1..3)."""
        t = self._past(t)
        return np.arccos(np.clip(self.case.pickoffs_at(t) @ self.spin_axis_case(t), -1.0, 1.0))

    def true_count_ratio(self, pickoff: int, t: float) -> float:
        """Noise-free count ratio from the exact geometry; nan when off the pattern."""
        return float(self.pattern.count_ratio(float(self.true_colatitudes(t)[pickoff - 1])))

    def place_spin_axis(self, s_lab: npt.ArrayLike) -> None:
        """Put the spin axis at s_lab now (test and set-up hook; the rotor must run free)."""
        if not self.rotor.free(self.now):
            raise RuntimeError("the rotor is not running free")
        self.rotor.place(self.now, s_lab)
