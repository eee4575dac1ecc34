"""Position geometry of the calibration (Charts I-5, I-6, II-17; Figures II-1..II-3).

Convention: T^XY_ij = X_i . Y_j; a column of T^BRm holds one rotary-frame axis in body
components. Positions 1-6: phi1 = 90 deg, the rotary axis R1 horizontal along south, the
table turning about +R1; R1 is +B1/-B1 (1/2), +B2/-B2 (3/4), +B3/-B3 (5/6). Positions 7-15:
phi1 = 0, phi2 = 90 deg, R = (U, N, -E): the first column of T^BRm is the body components
of up, the second those of north. 7/8, 9/10, 11/12: B1, B2, B3 up/down; 13, 14, 15:
(B1+B2)/sqrt2, (B1+B3)/sqrt2, (B2+B3)/sqrt2 up. The second of each pair is the first
turned 180 deg about O1 = R2 (phi3 + 180 deg): first and third columns negate, second stays.
Positions 7-12 use the resolver settings (so the T^BR) of 1-6; the survey gives the second
columns for m = 1, 3, 5, 13, 14, 15 only (Chart II-15 step 4).

The small body rotation of a setting away from its nominal T^BR is linear in the table's
error sources; ``TableErrorModel`` builds that map (see its docstring).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from procedures.isu.calibration.inputs import CalibrationData, Constants, TableGeometry
from procedures.isu.calibration.noise_spec import ARCSEC, NoiseSpec
from procedures.isu.calibration.vectors import cross3

E3 = np.eye(3)
_S2 = 1.0 / math.sqrt(2.0)

FIRST_COLUMN: dict[int, np.ndarray] = {
    1: E3[0],
    2: -E3[0],
    3: E3[1],
    4: -E3[1],
    5: E3[2],
    6: -E3[2],
    7: E3[0],
    8: -E3[0],
    9: E3[1],
    10: -E3[1],
    11: E3[2],
    12: -E3[2],
    13: _S2 * (E3[0] + E3[1]),
    14: _S2 * (E3[0] + E3[2]),
    15: _S2 * (E3[1] + E3[2]),
}
SURVEY_SOURCE = {m: (m if m in (13, 14, 15) else 2 * ((m - 1) % 6 // 2) + 1) for m in range(1, 16)}
UP_AXIS = {m: (((m - 1) % 6) // 2 if m <= 12 else None) for m in range(1, 16)}  # 0-based
PAIR = {m: ((m + 1) // 2 if m <= 12 else m) for m in range(1, 16)}


def t_br(m: int, c: Constants) -> np.ndarray:
    """Nominal T^BRm: first column by construction, second from the survey, third R1 x R2."""
    src = SURVEY_SOURCE[m]
    if src not in c.t_br_column2:
        raise ValueError(f"position {m} needs T12..T32 of T^BR{src} (Chart II-15 step 4)")
    c1 = FIRST_COLUMN[m]
    c2 = np.asarray(c.t_br_column2[src], dtype=float)
    return np.column_stack((c1, c2, cross3(c1, c2)))


def gimbal(p: float) -> np.ndarray:
    """Chart I-4 gimbal transform for angle p (rad)."""
    c, s = math.cos(p), math.sin(p)
    return np.array([[0.0, 1.0, 0.0], [c, 0.0, -s], [-s, 0.0, -c]])


def chart_i5_settings(t_bi: np.ndarray) -> dict[int, tuple[float, float]]:
    """Resolver settings (phi3, phi4), rad, for m = 1, 3, 5, 13, 14, 15 (Chart I-5).

    (cos phi3, sin phi3 sin phi4, sin phi3 cos phi4) = T^IB times the body vector to be put
    along R1; phi4 is arbitrary (taken 0) when sin phi3 vanishes.
    """
    out = {}
    for m in (1, 3, 5, 13, 14, 15):
        x = t_bi.T @ FIRST_COLUMN[m]
        p3 = math.acos(max(-1.0, min(1.0, float(x[0]))))
        p4 = math.atan2(float(x[1]), float(x[2])) if math.hypot(x[1], x[2]) > 1e-12 else 0.0
        out[m] = (p3, p4)
    return out


def setting_for(up: np.ndarray, t_bi: np.ndarray) -> tuple[float, float]:
    """Resolver setting (phi3, phi4), rad, that puts the body vector ``up`` along R1 (Chart
    I-5's relation, for any vector: the extra accelerometer positions of issue 19)."""
    x = t_bi.T @ (up / np.linalg.norm(up))
    p3 = math.acos(max(-1.0, min(1.0, float(x[0]))))
    p4 = math.atan2(float(x[1]), float(x[2])) if math.hypot(x[1], x[2]) > 1e-12 else 0.0
    return p3, p4


def frame_at(t_bi: np.ndarray, phi3: float, phi4: float) -> np.ndarray:
    """T^BR at a setting (Chart I-4's chain T^BI G(phi4) G(phi3)): columns R1, R2, R3 in
    body components; with phi1 = 0, phi2 = 90 and level corrections, R1 up and R2 north."""
    return t_bi @ gimbal(phi4) @ gimbal(phi3)


def extra_t_br(data: CalibrationData) -> dict[int, np.ndarray]:
    """Nominal T^BR of the extra accelerometer positions: their recorded up and north."""
    out = {}
    for m, p in data.extra_accel.items():
        up, north = np.asarray(p.up, dtype=float), np.asarray(p.north, dtype=float)
        out[m] = np.column_stack((up, north, np.cross(up, north)))
    return out


def extended_geometry(data: CalibrationData) -> TableGeometry | None:
    """The day's table geometry with the extra positions' resolver settings added."""
    if not data.extra_accel:
        return data.geometry
    g = data.geometry or default_geometry()
    extra = {m: p.setting_deg for m, p in data.extra_accel.items()}
    return g.model_copy(update={"settings_deg": {**g.settings_deg, **extra}})


DEFAULT_PHI0_DEG = (0.0, 90.0, 90.0, 0.0)  # B1 east, B2 north, B3 up with T^BI = I


def default_geometry() -> TableGeometry:
    """Nominal bolting (T^BI = I), Chart I-5 settings, position 0 with B1 east and B2 north."""
    s = chart_i5_settings(np.eye(3))
    return TableGeometry(
        t_bi=tuple(tuple(r) for r in np.eye(3)),
        phi0_deg=DEFAULT_PHI0_DEG,
        settings_deg={m: (math.degrees(a), math.degrees(b)) for m, (a, b) in s.items()},
    )


SettingKey = tuple[str, int]  # ("R", m) turning 1-6, ("G", m) gyro 7-15, ("A", m) accel 7-15


class TableErrorModel:
    """Linear map from the table's error sources to each setting's body rotation.

    The body rotation Delta of a setting (body components, small angles) is the rotation of
    the true body against the nominal T^BR the computations assume. With the survey's
    T^BI taken at position 0 (Chart I-2), Delta_s = delta(s) - delta(0), where delta(x) is
    the body's rotation against the chain the survey or the settings assume:

    * gimbal i off by e_i turns its inner frame about its own axis 1 (I1 for phi4, O1 for
      phi3, R1 for phi2); junction non-orthogonality n_XY turns everything inside by T^BX n_XY
      (``nonorthogonality``, per component);
    * at a setting, e_i = -(resolver cyclic error at the commanded reading) + servo scatter,
      the scatter independent per axis and per setting (every position re-commands phi1..phi4,
      ``procedures.isu.common.set_position``); at position 0, e_i = -(cyclic error at the reading);
    * the cyclic error of axis i is c1 sin p + c2 cos p + c3 sin 2p + c4 cos 2p with random
      coefficients (seeded phases): one set per axis, so settings at related angles (phi3 and
      phi3 + 180, positions 1 and 7, position 0 and 11) are correlated through it;
    * level-corrected settings (positions 7-15 and a position 0 with the rotary axis up,
      Charts II-17 and I-2 as built): the rotary frame keeps, about east, the bubble reading's
      error plus the difference of phi1's scatter before and after the correction, about
      north the bubble error (phi3's own error is in e3), about up (R1 = T2) e2 at phi2 plus
      n_RT's R1 component; the rest of n_RT and the base tilt are levelled out;
    * uncorrected static settings (``TableGeometry.uncorrected``, II-6.1): phi1 and phi3 carry
      the survey's level corrections, so the rotary frame keeps the survey's level error
      (in ``_delta0``) and, about east, phi1's scatter of its one setting; the tilt since the
      survey's reading is the covariance's (``t_level``);
    * the survey: mean of ``survey_readings`` autocollimator and level readings per mirror
      (isotropic body error autocollimator/sqrt(N), level error bubble/sqrt(N)), the
      base-azimuth step's error about up (``survey_azimuth_arcsec``), and phi1^0 entered as
      reading minus correction, which leaves phi1's scatter (``table_setting_arcsec``).
      A position 0 with the rotary axis not vertical is taken unlevelled: e1, e2 and the
      whole n_RT enter instead.
    * turning settings (1-6): only the body against the rotary frame matters.
    * a setting precision coarser than the table's (``TableGeometry.precision_arcsec``,
      II-6.1): phi3 and phi4 rounded, an error uniform over the precision, shared by the
      pair m, m + 1 (phi3 + 180 deg rounds alike).

    Not random, so not in the covariance: a static base tilt or azimuth the survey leaves in
    (e.g. the base azimuth at positions 7-15, a turn about up).
    """

    def __init__(self, geometry: TableGeometry | None, noise: NoiseSpec) -> None:
        g = geometry or default_geometry()
        self.noise = noise
        self.t_bi = np.asarray(g.t_bi, dtype=float)
        self.phi0 = tuple(math.radians(x) for x in g.phi0_deg)
        self.level0 = g.levelled  # rotary axis up: the survey reads the levels
        self.settings = {m: tuple(math.radians(x) for x in v) for m, v in g.settings_deg.items()}
        self.uncorrected = set(g.uncorrected)
        self.precision = {k: v * ARCSEC for k, v in g.precision_arcsec.items()}
        self._names: dict[object, int] = {}
        self._sig: list[float] = []
        no = noise.nonorthogonality_arcsec * ARCSEC
        for j in ("IO", "OR", "RT"):
            for i in range(3):
                self._source(("n", j, i), no)
        for axis in (1, 2, 3, 4):
            for i, s in enumerate(noise.resolver_coefficient_sigmas):
                self._source(("res", axis, i), s)
        root_n = math.sqrt(noise.survey_readings)
        for i in range(3):
            self._source(("ac", i), noise.autocollimator_arcsec * ARCSEC / root_n)
        if self.level0:
            sn = noise.table_setting_arcsec * ARCSEC
            self._source(("az0",), noise.survey_azimuth_arcsec * ARCSEC)
            self._source(("tau0E",), math.hypot(noise.bubble_sigma / root_n, sn))
            self._source(("tau0N",), noise.bubble_sigma / root_n)

    # ----- sources -----
    def _source(self, name: object, sigma: float) -> int:
        if name not in self._names:
            self._names[name] = len(self._sig)
            self._sig.append(sigma)
        return self._names[name]

    @property
    def sigmas(self) -> np.ndarray:
        return np.array(self._sig)

    # ----- frames at a setting -----
    def angles(self, m: int) -> tuple[float, float]:
        """Commanded (phi3, phi4), rad, of position m (positions 7-12 reuse 1-6)."""
        src = SURVEY_SOURCE.get(m, m)  # an extra position (16 on) has its own setting
        if src not in self.settings:
            raise ValueError(f"no resolver setting for position {src} in the table geometry")
        p3, p4 = self.settings[src]
        if m <= 12 and ((m - 1) % 6) % 2 == 1:  # 2, 4, 6, 8, 10, 12: phi3 + 180 deg
            p3 += math.pi
        return p3, p4

    def _add(self, rows: np.ndarray, name: object, vec: np.ndarray) -> None:
        rows[:, self._names[name]] += vec

    def _resolver(self, rows: np.ndarray, axis: int, p: float, vec: np.ndarray) -> None:
        """Add -e_axis(p) * vec (the gimbal stands short of the reading by the cyclic error)."""
        basis = (math.sin(p), math.cos(p), math.sin(2 * p), math.cos(2 * p))
        for i, b in enumerate(basis):
            rows[:, self._names[("res", axis, i)]] -= b * vec

    def _inside(self, rows: np.ndarray, t_bo: np.ndarray, t_br: np.ndarray) -> None:
        """Non-orthogonality of the I-O and O-R junctions."""
        for i in range(3):
            self._add(rows, ("n", "IO", i), t_bo[:, i])
            self._add(rows, ("n", "OR", i), t_br[:, i])

    def _levelled(self, rows: np.ndarray, t_be: np.ndarray, p2: float, names: tuple) -> None:
        """Rotary frame of a level-corrected setting (rotary axis up); t_be: up, east, north."""
        up, east, north = t_be[:, 0], t_be[:, 1], t_be[:, 2]
        self._resolver(rows, 2, p2, up)
        self._add(rows, ("n", "RT", 1), up)  # R1 = T2: n_RT's turn about the rotary axis
        az, tau_e, tau_n = names
        self._add(rows, az, up)
        self._add(rows, tau_e, east)
        self._add(rows, tau_n, north)

    def _delta0(self, n: int) -> np.ndarray:
        p1, p2, p3, p4 = self.phi0
        t_bo = self.t_bi @ gimbal(p4)
        t_br = t_bo @ gimbal(p3)
        t_bt = t_br @ gimbal(p2)
        rows = np.zeros((3, n))
        self._resolver(rows, 4, p4, self.t_bi[:, 0])
        self._resolver(rows, 3, p3, t_bo[:, 0])
        self._inside(rows, t_bo, t_br)
        if self.level0:
            t_be = t_bt @ gimbal(p1)
            self._levelled(rows, t_be, p2, (("az0",), ("tau0E",), ("tau0N",)))
        else:
            self._resolver(rows, 2, p2, t_br[:, 0])
            self._resolver(rows, 1, p1, t_bt[:, 0])
            for i in range(3):
                self._add(rows, ("n", "RT", i), t_bt[:, i])
        for i in range(3):
            self._add(rows, ("ac", i), E3[i])
        return rows

    def maps(
        self, keys: Iterable[SettingKey], nominal: dict[SettingKey, np.ndarray]
    ) -> dict[SettingKey, np.ndarray]:
        """3 x n_sources map of each setting's Delta; ``nominal`` gives each static T^BR."""
        keys = list(keys)
        nz = self.noise
        sn = nz.table_setting_arcsec * ARCSEC
        bub = nz.bubble_sigma
        for kind, m in keys:  # register the per-setting sources first (fixes n)
            self._source(("s3", kind, m), sn)
            self._source(("s4", kind, m), sn)
            if kind in self.precision:  # II-6.1: phi3, phi4 rounded, shared by the pair
                q = self.precision[kind] / math.sqrt(12.0)
                self._source(("q3", kind, PAIR.get(m, m)), q)
                self._source(("q4", kind, PAIR.get(m, m)), q)
            if kind != "R":
                self._source(("s2", kind, m), sn)
                if kind in self.uncorrected:  # one setting of phi1, no reading of its own
                    self._source(("tauE", kind, m), sn)
                    self._source(("tauN", kind, m), 0.0)
                else:
                    self._source(("tauE", kind, m), math.sqrt(bub * bub + 2 * sn * sn))
                    self._source(("tauN", kind, m), bub)
        n = len(self._sig)
        d0 = self._delta0(n)
        out = {}
        for key in keys:
            kind, m = key
            p3, p4 = self.angles(m)
            t_bo = self.t_bi @ gimbal(p4)
            t_brg = t_bo @ gimbal(p3)
            rows = np.zeros((3, n))
            self._resolver(rows, 4, p4, self.t_bi[:, 0])
            self._resolver(rows, 3, p3, t_bo[:, 0])
            self._add(rows, ("s4", kind, m), self.t_bi[:, 0])
            self._add(rows, ("s3", kind, m), t_bo[:, 0])
            if kind in self.precision:
                self._add(rows, ("q4", kind, PAIR.get(m, m)), self.t_bi[:, 0])
                self._add(rows, ("q3", kind, PAIR.get(m, m)), t_bo[:, 0])
            self._inside(rows, t_bo, t_brg)
            if kind != "R":  # positions 7-15: R = (U, N, -E), so up, east, north are
                t = nominal[key]  # the first column, minus the third and the second
                t_be = np.column_stack((t[:, 0], -t[:, 2], t[:, 1]))
                names = (("s2", kind, m), ("tauE", kind, m), ("tauN", kind, m))
                self._levelled(rows, t_be, math.pi / 2, names)
            out[key] = rows - d0
        return out
