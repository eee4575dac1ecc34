"""The line pattern on the ESG rotor (report 004, "Pattern Mechanization Equation", eqs. 1-3).

Rotor frame: z along the spin axis s, colatitude theta measured from s. The longitude phi
is counted in the sense in which a fixed pickoff's view advances over the turning rotor,
so a pickoff meets the smaller-phi edge of a line first (leading edge) and leaves the line
over its larger-phi edge (trailing edge). This is the sense in which eq. 3 reads
mu = phi2 - phi1 for the time from line 1 to line 2 with phi1 near 0 and phi2 near pi, and
it puts the logic line, which precedes line 1, at smaller phi than line 1.

Every edge is a level set F(theta, phi) = D of an edge function:
  great circle  F = b sin(theta) sin(phi) + c cos(theta), b = sin(i), c = cos(i);
  cosine        F = (K phi - cos theta) / g near phi = 0 and (-K (phi - pi) - cos theta) / g
                near phi = pi, g = sqrt(sin^2 theta + K^2 / sin^2 theta) (the surface
                gradient of the numerator), so F is the distance from the centre curve.
In both, F grows with phi near 0 and falls with phi near pi, and it is (to 0.5 % for the
great circle) the perpendicular distance on the 1-inch rotor, in inches.

One grit-blast pass lays both lines (the report's two trailing edges come from opposite
ends of the nozzle), so both lines are the band F in [d0 - w/2, d0 + w/2]: line 1's
trailing edge is F = d0 + w/2, line 2's is F = d0 - w/2. The count ratio depends on the two
trailing-edge values symmetrically, so it equals the contract's mu = phi2 - phi1 formula.
The logic line (its own nozzle set-up, offset d_logic) is the band of width w_l whose
trailing edge lies `logic_gap_in` below line 1's leading edge, on line 1's side only.

Flaws of a real pattern, all seeded and fixed properties of the rotor:
  * d0: tool set-up offset of the pattern pass (sd 0.0005 inch);
  * application error: per edge a Chebyshev series of degree 4 in colatitude, scaled to a
    peak of 150 micro-inch over the pattern (spindle runout during grit blast and the
    like; smooth, so the 7th-order calibration polynomial absorbs most of it);
  * edge roughness: per edge a stationary Gaussian process of the arc length along the
    edge (sum of 128 random Fourier modes, rms 40 micro-inch, Gaussian correlation length
    0.004 inch, tabulated every 0.00067 inch and interpolated linearly), so a given
    colatitude always sees the same roughness.
The edge longitudes solve the perturbed edge equation exactly (closed form: the
perturbations are functions of colatitude, and F is linear in sin(phi) or phi), not the
report's approximate nominal mechanization (eqs. 7-10).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import NamedTuple, overload

import numpy as np
import numpy.typing as npt

from sim.rng import stream

EDGE_NAMES = ("logic_lead", "logic_trail", "line1_lead", "line1_trail", "line2_lead",
              "line2_trail")
_NEAR_PI = np.array([name.startswith("line2") for name in EDGE_NAMES])
KINDS = ("great_circle", "cosine")


class Edges(NamedTuple):
    """Rotor longitudes (rad) of the six edges at each colatitude; line 2 lies near pi."""

    logic_lead: np.ndarray
    logic_trail: np.ndarray
    line1_lead: np.ndarray
    line1_trail: np.ndarray
    line2_lead: np.ndarray
    line2_trail: np.ndarray
    visible: np.ndarray  # bool: the pickoff's circle crosses the pattern


@dataclass(frozen=True)
class PatternSpec:
    """Pattern geometry (inches on the 1-inch rotor, i.e. radians of arc) and its flaws."""

    kind: str = "great_circle"
    inclination_deg: float = 56.0  # great circle: inclination at the equator
    top_colatitude_deg: float = 43.0  # lines end at latitude 47 in both hemispheres
    width_in: float = 0.060  # pattern line (nozzle 0.003 x 0.060)
    logic_width_in: float = 0.030
    logic_gap_in: float = 0.060  # logic trailing edge to line 1 leading edge
    d0_sd_in: float = 0.0005  # tool set-up offset of the pattern pass
    logic_offset_sd_in: float = 0.002  # set-up offset of the logic-line pass
    application_in: float = 150e-6  # peak smooth application error per edge
    application_degree: int = 4
    roughness_rms_in: float = 40e-6
    roughness_corr_in: float = 0.004
    roughness_modes: int = 128
    cosine_k: float | None = None  # None: from the top colatitude and the clearance
    cosine_clearance_in: float = 0.060  # between neighbouring lines at the extremities


def _fourier_table(n: int, h: float, k: np.ndarray, phase: np.ndarray) -> np.ndarray:
    """sum_m cos(s k_m + phase_m) at s = 0, h, ..., (n - 1) h, by angle addition: with
    s = (q B + r) h, each term is Re(exp(i (q B h k_m + phase_m)) exp(i r h k_m)), so the
    table is one product of two B-row matrices of exponentials (B about sqrt(n)) instead
    of n cosines per mode (issue 17: 2.6 million cosines were 0.07 s of the ESG rack's
    assembly). The arguments are as large as the direct sum's, so is their rounding."""
    b = max(1, math.isqrt(n - 1) + 1)
    q = np.arange(-(-n // b)) * (b * h)
    r = np.arange(b) * h
    hi = q[:, None] * k[None, :] + phase[None, :]
    lo = r[:, None] * k[None, :]
    table = np.cos(hi) @ np.cos(lo).T - np.sin(hi) @ np.sin(lo).T
    return table.ravel()[:n]


def _edge_values(spec: PatternSpec, d0: float, d_logic: float) -> np.ndarray:
    """Nominal F value of each edge, in EDGE_NAMES order."""
    w, wl, gap = spec.width_in, spec.logic_width_in, spec.logic_gap_in
    logic_trail = d0 - w / 2 - gap + d_logic
    return np.array([logic_trail - wl, logic_trail, d0 - w / 2, d0 + w / 2, d0 + w / 2,
                     d0 - w / 2])


def _cosine_k(spec: PatternSpec) -> float:
    """Smallest K leaving the clearance between neighbouring lines at both extremities.

    The report's longitude allotment (section "Pattern line spacing") generalised to this
    gyro's line widths: at the top the gap is line 1 trailing to line 2 leading, at the
    bottom line 2 trailing to the logic line's leading edge; a longitude gap dphi is a
    perpendicular distance dphi sin(theta) sin(delta), tan(delta) = K / sin^2(theta)."""
    top = math.radians(spec.top_colatitude_deg)
    vals = _edge_values(spec, 0.0, 0.0)

    def clearance(k: float) -> float:
        gaps = []
        for th, (a, b, wrap) in ((top, (3, 4, 0.0)), (math.pi - top, (5, 0, 2 * math.pi))):
            g = math.sqrt(math.sin(th) ** 2 + k * k / math.sin(th) ** 2)
            h = (math.cos(th) + vals * g) / k
            phi = np.where(_NEAR_PI, math.pi - h, h)
            dphi = phi[b] + wrap - phi[a]
            sin_delta = math.sin(math.atan(k / math.sin(th) ** 2))
            gaps.append(dphi * math.sin(th) * sin_delta)
        return min(gaps) - spec.cosine_clearance_in

    lo, hi = 0.05, 5.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if clearance(mid) >= 0.0 else (mid, hi)
    return hi


class Pattern:
    """One patterned rotor: edge longitudes and count ratio versus colatitude."""

    def __init__(self, spec: PatternSpec | None = None, seed: int = 0,
                 perturbed: bool = True) -> None:
        self.spec = spec = spec or PatternSpec()
        if spec.kind not in KINDS:
            raise ValueError(f"pattern kind must be one of {KINDS}, not {spec.kind!r}")
        incl = math.radians(spec.inclination_deg)
        self.b, self.c = math.sin(incl), math.cos(incl)
        self.top = math.radians(spec.top_colatitude_deg)
        self.k = 0.0
        if spec.kind == "cosine":
            self.k = spec.cosine_k if spec.cosine_k is not None else _cosine_k(spec)
        rng = stream(seed, "esg", "pattern", "setup")
        d0, d_logic = (rng.normal(0.0, [spec.d0_sd_in, spec.logic_offset_sd_in])
                       if perturbed else (0.0, 0.0))
        self.d0, self.d_logic = float(d0), float(d_logic)
        self.nominal = _edge_values(spec, self.d0, self.d_logic)
        n = len(EDGE_NAMES)
        deg, modes = spec.application_degree, spec.roughness_modes
        self._cheb = np.zeros((n, deg + 1))
        self._kw = np.zeros((n, modes))
        self._ph = np.zeros((n, modes))
        self._ramp = 0.0
        if perturbed:
            u = np.linspace(-1.0, 1.0, 401)
            for j, name in enumerate(EDGE_NAMES):
                r = stream(seed, "esg", "pattern", "edge", name)
                coef = r.normal(0.0, 1.0, deg + 1) / (1.0 + np.arange(deg + 1))
                peak = np.max(np.abs(np.polynomial.chebyshev.chebval(u, coef)))
                self._cheb[j] = coef * spec.application_in / peak
                self._kw[j] = r.normal(0.0, 1.0 / spec.roughness_corr_in, modes)
                self._ph[j] = r.uniform(0.0, 2.0 * math.pi, modes)
            self._ramp = spec.roughness_rms_in * math.sqrt(2.0 / modes)
        self._grid_th, self._grid_s = self._arc_length_grid()
        self._rough_h = spec.roughness_corr_in / 6.0
        self._rough = np.zeros((n, 2))
        if self._ramp > 0.0:
            # the Fourier sums tabulated every corr/6 of arc length (interpolation error
            # about 1 % of the rms); the table is the rotor's fixed roughness
            n_s = int(np.max(self._grid_s[:, -1]) / self._rough_h) + 2
            self._rough = self._ramp * np.array([
                _fourier_table(n_s, self._rough_h, self._kw[j], self._ph[j])
                for j in range(n)])

    # ----- geometry -----
    def _solve(self, theta: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Longitude on each edge's branch where F = d (rows: edges); and whether it exists."""
        st, ct = np.sin(theta), np.cos(theta)
        if self.spec.kind == "great_circle":
            x = (d - self.c * ct) / (self.b * st)
            ok = np.abs(x) <= 1.0
            h = np.arcsin(np.clip(x, -1.0, 1.0))
        else:
            g = np.sqrt(st * st + self.k * self.k / (st * st))
            h = (ct + d * g) / self.k
            ok = np.ones_like(h, dtype=bool)
        near_pi = _NEAR_PI.reshape((-1,) + (1,) * (np.ndim(h) - 1))
        return np.where(near_pi, math.pi - h, h), ok

    def edge_function(self, name: str, theta: npt.ArrayLike, phi: npt.ArrayLike) -> np.ndarray:
        """F(theta, phi) of the named edge's family (for checking solutions)."""
        theta, phi = np.asarray(theta, float), np.asarray(phi, float)
        st, ct = np.sin(theta), np.cos(theta)
        if self.spec.kind == "great_circle":
            return self.b * st * np.sin(phi) + self.c * ct
        g = np.sqrt(st * st + self.k * self.k / (st * st))
        lon = math.pi - phi if name.startswith("line2") else phi
        return (self.k * lon - ct) / g

    def _arc_length_grid(self) -> tuple[np.ndarray, np.ndarray]:
        """Arc length along each nominal edge versus colatitude (the roughness coordinate)."""
        th = np.linspace(self.top - math.radians(0.5), math.pi - self.top + math.radians(0.5),
                         2001)
        phi, _ = self._solve(th[None, :], self.nominal[:, None])
        ds = np.hypot(np.diff(th)[None, :], np.sin(0.5 * (th[1:] + th[:-1])) * np.diff(phi))
        s = np.concatenate([np.zeros((len(EDGE_NAMES), 1)), np.cumsum(ds, axis=1)], axis=1)
        return th, s

    def edge_offsets(self, theta: npt.ArrayLike) -> np.ndarray:
        """F value D_e(theta) of every edge, flaws included; shape (6, n)."""
        theta = np.atleast_1d(np.asarray(theta, float))
        u = (theta - 0.5 * math.pi) / (0.5 * math.pi - self.top)
        t_prev, t_cur = np.ones_like(u), u
        app = self._cheb[:, :1] * t_prev
        for j in range(1, self._cheb.shape[1]):
            app = app + self._cheb[:, j:j + 1] * t_cur
            t_prev, t_cur = t_cur, 2.0 * u * t_cur - t_prev
        d = self.nominal[:, None] + app
        if self._ramp > 0.0:
            g = self._grid_th
            x = np.clip((theta - g[0]) / (g[1] - g[0]), 0.0, len(g) - 1.000001)
            i = x.astype(int)
            f = x - i
            s = (self._grid_s[:, i] * (1.0 - f) + self._grid_s[:, i + 1] * f) / self._rough_h
            j = np.minimum(s.astype(int), self._rough.shape[1] - 2)
            f = s - j
            rows = np.arange(len(EDGE_NAMES))[:, None]
            d = d + self._rough[rows, j] * (1.0 - f) + self._rough[rows, j + 1] * f
        return d

    def edge_offset(self, name: str, theta: npt.ArrayLike) -> np.ndarray:
        """F value of one edge at colatitude(s) theta, flaws included."""
        return self.edge_offsets(theta)[EDGE_NAMES.index(name)]

    def visible(self, theta: npt.ArrayLike) -> np.ndarray:
        """Whether a pickoff at colatitude theta crosses the patterned band."""
        theta = np.atleast_1d(np.asarray(theta, float))
        return (theta >= self.top) & (theta <= math.pi - self.top)

    def edges(self, theta: npt.ArrayLike) -> Edges:
        """Edge longitudes (rad) at colatitude(s) theta (rad), vectorised."""
        theta = np.atleast_1d(np.asarray(theta, float))
        phi, ok = self._solve(theta[None, :], self.edge_offsets(theta))
        vis = self.visible(theta) & np.all(ok, axis=0)
        return Edges._make((*phi, vis))  # phi: the six edges in Edges' order

    @overload
    def count_ratio(self, theta: float) -> float: ...
    @overload
    def count_ratio(self, theta: np.ndarray) -> np.ndarray: ...
    def count_ratio(self, theta: float | np.ndarray) -> float | np.ndarray:
        """Noise-free count ratio (phi2 - phi1) / 2 pi of the trailing edges; nan off-pattern."""
        scalar = np.ndim(theta) == 0
        e = self.edges(theta)
        cr = np.where(e.visible, (e.line2_trail - e.line1_trail) / (2.0 * math.pi), np.nan)
        return float(cr[0]) if scalar else cr


@functools.lru_cache(maxsize=8)
def nominal_pattern(spec: PatternSpec | None = None) -> Pattern:
    """The flawless pattern of a spec (set-up offsets, application error, roughness zero)."""
    return Pattern(spec or PatternSpec(), seed=0, perturbed=False)
