"""Data-processor signal chain for one data line (report 004, "SDESG Data Processor
Description", the HIT circuit under "Readout Electronics Modification", the adjustments
under "Before data taking", Appendix A).

Per selected pickoff, the pulse train of the last REV + 3 revolutions before the line time
is built at once with numpy (no simulation event per revolution or pulse):
  * genuine pulses: logic line, line 1, line 2, from the edge longitudes of
    sim.esg.pattern at the pickoff's colatitude (interpolated linearly across the window)
    and the instantaneous rotor speed; height 2.1 V per pickoff within +-5 % (the lamp
    currents were trimmed to 2.1 V), 1 % from pulse to pulse;
  * arc-mark noise pulses: Poisson in time, 0.02 per revolution per pickoff, width uniform
    0.3-4 us, height uniform 0.5-3 V; a fraction `arc_wide_fraction` (0 by default) is
    30-60 us wide so that it passes the width discriminator (a test knob);
  * pulses that overlap merge into one (union in time, the larger height): a dark
    blemish on a dark line changes nothing, one across an edge extends the line.
The Height Insensitive Trigger fires where a pulse falls through 50 % of its own height,
so a trigger time is the geometric edge crossing plus a fixed channel delay (300 ns,
+-10 ns between channels) plus 80 ns rms Gaussian jitter per edge; with 10 revolutions at
about 244 rps this gives a line-to-line count-ratio scatter of about 1e-5 (Appendix A).
Pulses below the HIT threshold or narrower than the width discriminator are ignored.
Every accepted pulse triggers the logic-delay multivibrator; an accepted pulse whose
trailing edge comes within `logic_delay_us` of the previous accepted pulse's trailing
edge starts the counter (normally line 1 after the logic line), and the next accepted
pulse stops it (line 2). C1 of a pickoff is the sum over the last REV start-stop pairs;
the period sum runs from a start to the REV-th next start on pickoff A (line 1 to
line 1). Counts are whole cycles of the 100 MHz clock multiplied from the 1 MHz standard,
whose fractional frequency offset is seeded (sd 1e-9).

Genuine pulse widths at 250 rps: the 0.060-inch lines are 46 us at the equator and wider
elsewhere, the 0.030-inch logic line 23 us at its narrowest, so the default 20 us
discriminator passes them all over colatitude 43-137 deg (at speeds up to about 290 rps)
and rejects every ordinary arc mark. The default logic delay is the pattern's largest
logic-to-line-1 trailing-edge time at 250 rps (221 us, at colatitude 43 deg) plus
20 us, rounded up to a whole microsecond, as the report set it up.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from sim.esg.pattern import Pattern, PatternSpec, nominal_pattern
from sim.rng import stream
from sim.timebase import ticks

LOGIC, LINE1, LINE2, NOISE = 0, 1, 2, -1
_KINDS = np.array([LOGIC, LINE1, LINE2])
TWO_PI = 2.0 * math.pi


@functools.lru_cache(maxsize=8)
def default_logic_delay_us(spec: PatternSpec | None = None, spin_rps: float = 250.0) -> float:
    """Largest logic-to-line-1 trailing-edge time over the pattern, plus 20 us."""
    p = nominal_pattern(spec or PatternSpec())
    th = np.linspace(p.top, math.pi - p.top, 2001)
    e = p.edges(th)
    dt = (e.line1_trail - e.logic_trail) / (TWO_PI * spin_rps)
    return float(math.ceil(np.max(dt) * 1e6 + 20.0))


@dataclass
class ProcessorSettings:
    """Front-panel adjustments of the data processor (REV is passed separately)."""

    threshold_v: float = 1.5  # HIT threshold
    min_width_us: float = 20.0  # pulse-width discriminator, 2..24
    logic_delay_us: float = field(default_factory=default_logic_delay_us)


@dataclass
class LineCounts:
    """One data line: 100 MHz counts summed over the revolutions."""

    c1: dict[int, int]  # pickoff -> C1 sum; 0 for an unselected or off-pattern pickoff
    period_sum: int  # on pickoff A, line-1 trailing edge to line-1 trailing edge
    rejected_pulses: int  # noise pulses that had no effect on the counts
    gated_wrong: bool  # truth: a noise pulse started or stopped a count (not on the wire)


@dataclass(frozen=True)
class SignalSpec:
    """Pickoff pulses, arc-mark noise, HIT timing and the clock."""

    pulse_height_v: float = 2.1
    pulse_height_tol: float = 0.05  # per pickoff, uniform +-
    pulse_height_scatter: float = 0.01  # pulse to pulse, rms fraction
    jitter_ns: float = 80.0  # rms per edge
    hit_delay_ns: float = 300.0
    hit_delay_spread_ns: float = 10.0
    arc_rate_per_rev: float = 0.02  # per pickoff
    arc_width_us: tuple[float, float] = (0.3, 4.0)
    arc_height_v: tuple[float, float] = (0.5, 3.0)
    arc_wide_fraction: float = 0.0
    arc_wide_width_us: tuple[float, float] = (30.0, 60.0)
    clock_hz: float = 100e6
    clock_offset_sd: float = 1e-9


@dataclass(frozen=True)
class Channel:
    """Geometry of one pickoff over the window of a data line."""

    pickoff: int
    theta_end: float  # colatitude at the line time, rad
    theta_start: float  # at the start of the window
    view_end: float  # rotor longitude under the pickoff at the line time, rad
    height_v: float
    delay_s: float  # fixed HIT delay of the channel


@dataclass(frozen=True)
class Clock:
    """The counters' 100 MHz clock: frequency and phase."""

    hz: float
    phase: float  # cycles at t = 0

    def counts(self, t_end: float, a: np.ndarray, b: np.ndarray) -> int:
        """Whole clock cycles in [t_end + a, t_end + b), summed over the pairs."""
        base = (t_end * self.hz + self.phase) % 1.0
        return int(np.sum(np.floor(base + np.asarray(b) * self.hz))
                   - np.sum(np.floor(base + np.asarray(a) * self.hz)))


def make_clock(seed: int, sig: SignalSpec) -> Clock:
    rng = stream(seed, "esg", "clock")
    off = float(rng.normal(0.0, sig.clock_offset_sd))
    return Clock(sig.clock_hz * (1.0 + off), float(rng.uniform()))


@dataclass
class _Train:
    """Merged pulses of one channel, in time order (times relative to the line time)."""

    lead: list[float]
    trail: list[float]
    height: list[float]
    kind: list[int]  # kind of the pulse that sets the trailing edge
    noise: list[int]  # number of noise pulses merged into each
    n_noise: int


def _genuine(phi: np.ndarray, vis: np.ndarray, ch: Channel, w: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lead and trail times (s, <= 0) and kinds of the pattern pulses, flat arrays.

    phi: (6, n_rev) edge longitudes per revolution, newest first; vis: (n_rev,) bool."""
    n_rev = len(vis)
    if not vis.any():
        empty = np.zeros(0)
        return empty, empty, np.zeros(0, dtype=int)
    m = np.arange(n_rev)
    first = int(np.argmax(vis))
    trails = phi[1::2]  # rows 1, 3, 5: the trailing edges (0, 2, 4 lead)
    ref = trails[:, first]
    delta = ((ref - ch.view_end) % TWO_PI) - TWO_PI
    trail = (delta[:, None] + (trails - ref[:, None]) - TWO_PI * m[None, :]) / w
    lead = trail - (trails - phi[0::2]) / w
    kind = np.repeat(_KINDS, n_rev)
    keep = np.tile(vis, 3)
    return lead.ravel()[keep], trail.ravel()[keep], kind[keep]


def _edges_per_revolution(pattern: Pattern, ch: Channel, ends: tuple[np.ndarray, np.ndarray],
                          n_rev: int) -> tuple[np.ndarray, np.ndarray]:
    """Edge longitudes (6, n_rev) and visibility at each revolution of the window."""
    frac = (np.arange(n_rev) + 0.5) / n_rev
    phi_ends, vis_ends = ends
    if bool(np.all(vis_ends)):
        phi = phi_ends[:, :1] + (phi_ends[:, 1:] - phi_ends[:, :1]) * frac[None, :]
        return phi, np.ones(n_rev, dtype=bool)
    th = ch.theta_end + (ch.theta_start - ch.theta_end) * frac
    e = pattern.edges(th)
    return np.array(e[:6]), e.visible


def _train(sig: SignalSpec, ch: Channel, seed: int, key: int, phi: np.ndarray,
           vis: np.ndarray, rps: float) -> _Train:
    """All pulses of one channel over the window, jittered, merged, in time order."""
    n_rev = len(vis)
    lead, trail, kind = _genuine(phi, vis, ch, TWO_PI * rps)
    n = len(lead)
    rng = stream(seed, "esg", "pulses", ch.pickoff, key)
    # fixed numbers of draws first, so the jitter does not depend on the arc marks
    jit = rng.normal(0.0, sig.jitter_ns * 1e-9, (2, 3 * n_rev))
    hs = rng.normal(1.0, sig.pulse_height_scatter, 3 * n_rev)[:n] * ch.height_v
    lead = lead + ch.delay_s + jit[0, :n]
    trail = trail + ch.delay_s + jit[1, :n]
    n_arc = int(rng.poisson(sig.arc_rate_per_rev * n_rev))
    if n_arc:
        a_lead = rng.uniform(-n_rev / rps, 0.0, n_arc)
        wide = rng.uniform(0.0, 1.0, n_arc) < sig.arc_wide_fraction
        width = np.where(wide, rng.uniform(*sig.arc_wide_width_us, n_arc),
                         rng.uniform(*sig.arc_width_us, n_arc)) * 1e-6
        a_h = rng.uniform(*sig.arc_height_v, n_arc)
        a_trail = a_lead + width
        ok = a_trail <= 0.0
        lead = np.concatenate([lead, a_lead[ok]])
        trail = np.concatenate([trail, a_trail[ok]])
        hs = np.concatenate([hs, a_h[ok]])
        kind = np.concatenate([kind, np.full(int(ok.sum()), NOISE)])
    n_noise = len(lead) - n
    if len(lead) == 0:
        return _Train([], [], [], [], [], 0)
    order = np.argsort(lead, kind="stable")
    lead, trail, hs, kind = lead[order], trail[order], hs[order], kind[order]
    # overlapping pulses merge: a new pulse starts after every earlier pulse has ended
    reach = np.maximum.accumulate(trail)
    new = np.ones(len(lead), dtype=bool)
    new[1:] = lead[1:] > reach[:-1]
    starts = np.flatnonzero(new)
    group = np.cumsum(new) - 1
    g_trail = np.maximum.reduceat(trail, starts)
    g_height = np.maximum.reduceat(hs, starts)
    setter = np.flatnonzero(trail == g_trail[group])
    g_kind = np.empty(len(starts), dtype=int)
    g_kind[group[setter]] = kind[setter]
    g_noise = np.bincount(group, weights=(kind == NOISE), minlength=len(starts))
    return _Train(lead[starts].tolist(), g_trail.tolist(), g_height.tolist(), g_kind.tolist(),
                  g_noise.astype(int).tolist(), n_noise)


def _gate(t: _Train, s: ProcessorSettings) -> tuple[list[tuple[int, int, int]],
                                                    list[tuple[int, int]]]:
    """Logic-delay gating: (arm, start, stop) pairs and all (arm, start) starts."""
    min_w, delay = s.min_width_us * 1e-6, s.logic_delay_us * 1e-6
    pairs: list[tuple[int, int, int]] = []
    starts: list[tuple[int, int]] = []
    prev = -1
    running: tuple[int, int] | None = None
    for i in range(len(t.lead)):
        if t.height[i] < s.threshold_v or t.trail[i] - t.lead[i] < min_w:
            continue
        if running is not None:
            pairs.append((running[0], running[1], i))
            running = None
        elif prev >= 0 and t.trail[i] - t.trail[prev] <= delay:
            running = (prev, i)
            starts.append(running)
        prev = i
    return pairs, starts


def measure_line(pattern: Pattern, sig: SignalSpec, settings: ProcessorSettings, seed: int,
                 t_end: float, rps: float, revolutions: int, channels: list[Channel],
                 pickoff_a: int, clock: Clock) -> LineCounts:
    """Counts of one data line for the revolutions ending at t_end (s), speed rps."""
    n_rev = revolutions + 3
    key = ticks(t_end)
    e = pattern.edges([x for ch in channels for x in (ch.theta_end, ch.theta_start)])
    phi_all, vis_all = np.array(e[:6]), e.visible
    c1 = {1: 0, 2: 0, 3: 0}
    period, wrong, n_noise, n_used = 0, False, 0, 0
    for j, ch in enumerate(channels):
        ends = (phi_all[:, 2 * j:2 * j + 2], vis_all[2 * j:2 * j + 2])
        phi, vis = _edges_per_revolution(pattern, ch, ends, n_rev)
        tr = _train(sig, ch, seed, key, phi, vis, rps)
        pairs, starts = _gate(tr, settings)
        n_noise += tr.n_noise
        used: set[int] = set()
        if len(pairs) >= revolutions:
            use = pairs[-revolutions:]
            used.update(i for p in use for i in p)
            a = np.array([tr.trail[p[1]] for p in use])
            b = np.array([tr.trail[p[2]] for p in use])
            c1[ch.pickoff] = clock.counts(t_end, a, b)
            wrong |= any((tr.kind[p[0]], tr.kind[p[1]], tr.kind[p[2]]) != (LOGIC, LINE1, LINE2)
                         for p in use)
        if ch.pickoff == pickoff_a and len(starts) >= revolutions + 1:
            use_s = starts[-revolutions - 1:]
            used.update(i for p in use_s for i in p)
            period = clock.counts(t_end, np.array([tr.trail[use_s[0][1]]]),
                                  np.array([tr.trail[use_s[-1][1]]]))
            wrong |= any((tr.kind[p[0]], tr.kind[p[1]]) != (LOGIC, LINE1) for p in use_s)
        n_used += sum(tr.noise[i] for i in used if tr.kind[i] == NOISE)
    return LineCounts(c1, period, n_noise - n_used, bool(wrong))
