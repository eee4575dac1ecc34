"""Plausibility of what a procedure reads: nothing the instruments could not have reported,
and no single reading that disagrees with its repetitions, reaches a computation.

The checks on readings (those on results live with each result: ``alignment.checks``,
``calibration.checks``; the instrument-specific readings are in ``procedures.isu.readings``):

* range: a reading outside what the instrument can report (its data sheet, as in
  docs/protocols.md) is refused; so is a status reply that is no word the instrument says
  (``read_word``) and a reply the driver itself could not parse (``guarded``);
* agreement: repeated readings of one quantity are compared with their median in units of
  the noise the laboratory's specification (``NoiseSpec``) predicts for them, never less than
  their own robust scatter (``AgreeingReadings``); a value read once is read twice
  (``read_agreeing``).

A refused reading is read again (at most ``MAX_REREADS`` times per quantity, each re-read
recorded in the enclosing ``rereads()`` block) and the step stops, naming the instrument,
when the re-reads do not bring it into agreement: :class:`Implausible`, whose message starts
with the instrument and its link as a driver error does, so the step's ``ProcedureError``
names the chart, the step and the instrument. These checks do not rely on the drivers' own
reply checks: a reply can be well formed and still wrong (a digit changed into another).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike

from procedures.isu.calibration.noise_spec import ARCSEC, NoiseSpec
from procedures.medians import median
from station.errors import CheckFailed

T = TypeVar("T")
K_READING = 6.0  # a reading this many sigma from its repetitions' median is an outlier
MAX_REREADS = 3  # re-reads of one quantity's outliers before the step stops
MAD_TO_SIGMA = 1.4826  # median absolute deviation of a normal sample, in sigma
# Instrument data sheets (docs/protocols.md): what each can report at all.
LEVEL_RANGE_ARCSEC = 120.0  # bubble levels: +/-120 arcsec, else ERR 40
AC_ZENITH_RANGE_DEG = (60.0, 120.0)  # autocollimator mount
AC_FIELD_DEG = 0.5  # autocollimator field of view (radius), deg


class Implausible(CheckFailed):
    """A reading or a result that contradicts the instrument's range, its repetitions or what
    the survey and the site already know; the message starts with what is wrong (a failed
    check: it carries the chart and step it was raised in)."""

    def __init__(self, source: str, message: str) -> None:
        self.source = source
        self.detail = message
        super().__init__(f"{source}: {message}")


def source_of(driver: object) -> str:
    """``name (link)`` of a driver, as its own errors print it."""
    name = getattr(driver, "name", type(driver).__name__)
    link = getattr(driver, "url", None) or getattr(driver, "link", None)
    return f"{name} ({link})" if link else str(name)


def check_range(driver: object, what: str, value: float, lo: float, hi: float,
                unit: str) -> float:
    """``value`` if it lies in [lo, hi] (and is finite), else Implausible naming the driver."""
    if not (math.isfinite(value) and lo <= value <= hi):
        raise Implausible(source_of(driver), f"{what} {value:g} {unit} is outside what the "
                          f"instrument can report ([{lo:g}, {hi:g}] {unit})")
    return value


def level_reading(driver: object, values: Sequence[float]) -> tuple[float, float]:
    """A bubble-level reading (phi1, phi3 corrections, arcsec) inside the levels' range."""
    c1, c3 = (check_range(driver, f"level correction for phi{ax}", float(v),
                          -LEVEL_RANGE_ARCSEC, LEVEL_RANGE_ARCSEC, "arcsec")
              for ax, v in zip((1, 3), values, strict=True))
    return c1, c3


def autocollimator_reading(driver: object, values: Sequence[float]) -> tuple[float, float]:
    """An autocollimator reading (azimuth, zenith, deg) the mount and field of view allow."""
    az, zen = (float(v) for v in values)
    check_range(driver, "azimuth", az, 0.0, 360.0, "deg")
    lo, hi = AC_ZENITH_RANGE_DEG
    check_range(driver, "zenith", zen, lo - AC_FIELD_DEG, hi + AC_FIELD_DEG, "deg")
    return az, zen


# ----------------------------------------------------------------------------- re-reads

_LOG: ContextVar[list[dict] | None] = ContextVar("rereads", default=None)


@contextmanager
def rereads() -> Iterator[list[dict]]:
    """Collect the re-reads made inside the block (a step records them with its reading)."""
    log: list[dict] = []
    token = _LOG.set(log)
    try:
        yield log
    finally:
        _LOG.reset(token)


def note_reread(entry: dict) -> None:
    """Record one re-read in the enclosing ``rereads()`` block, if any."""
    log = _LOG.get()
    if log is not None:
        log.append(entry)


def with_rereads(reading: dict, log: list[dict]) -> dict:
    """A step's reading with its re-reads added (nothing added when there were none, so a
    day without them records exactly what it did before)."""
    return {**reading, "rereads": list(log)} if log else reading


PARSE_ERRORS = (ValueError, ArithmeticError, IndexError)  # a driver that trusted a reply


def guarded(driver: object, what: str, read: Callable[[], T]) -> T:
    """``read()``, where a reply the driver failed to parse (a builtin error out of it, e.g.
    a float() of a garbled number) counts as a garbled reply: read again (at most
    MAX_REREADS times, recorded), then Implausible naming the driver and what was read."""
    errors: list[str] = []
    while True:
        try:
            got = read()
        except PARSE_ERRORS as e:
            errors.append(str(e))
            if len(errors) > MAX_REREADS:
                raise Implausible(source_of(driver), f"{what}: replies the driver could not "
                                  f"read ({'; '.join(errors)}): garbled replies") from e
            continue
        if errors:
            note_reread({"instrument": str(getattr(driver, "name", "")), "what": what,
                         "was": errors, "now": "read"})
        return got


def read_word(driver: object, read: Callable[[], str], words: Sequence[str], what: str,
              first: str | None = None) -> str:
    """A reply from a known vocabulary (a status word); anything else is a garbled reply,
    read again (at most MAX_REREADS times, recorded) before the step stops. ``first``: a
    reply already received, judged before reading again."""
    got: list[str] = []
    for i in range(MAX_REREADS + 1):
        r = first if (i == 0 and first is not None) else read()
        if r in words:
            if got:
                note_reread({"instrument": str(getattr(driver, "name", "")), "what": what,
                             "was": got, "now": r})
            return r
        got.append(r)
    raise Implausible(source_of(driver), f"{what}: replies {got!r} are none of "
                      f"{', '.join(words)} (garbled replies)")


def read_agreeing(driver: object, read: Callable[[], float], what: str,
                  tol: float = 0.0) -> float:
    """A value read twice: the two readings must agree within ``tol``; if they do not, read
    again until two consecutive readings agree (at most MAX_REREADS more, recorded)."""
    got = [read()]
    for _ in range(MAX_REREADS + 1):
        got.append(read())
        if abs(got[-1] - got[-2]) <= tol:
            if len(got) > 2:
                note_reread({"instrument": str(getattr(driver, "name", "")), "what": what,
                             "was": got[:-2], "now": got[-1]})
            return got[-1]
    raise Implausible(source_of(driver), f"{what}: consecutive readings {got} never agree "
                      f"(within {tol:g}): garbled replies")


# ----------------------------------------------------------------------------- agreement


def deviations(values: np.ndarray, sigma: np.ndarray | float) -> np.ndarray:
    """|value - median| per reading and component, in units of max(sigma, robust scatter).

    ``values`` is n x d (n readings of d components); ``sigma`` the known 1-sigma scatter of
    one reading about the median, per component. The robust scatter (1.4826 MAD) keeps the
    check honest when the laboratory is noisier than its specification.
    """
    v = np.asarray(values, dtype=float)
    if v.ndim == 1:
        v = v[:, None]
    med = median(v, axis=0)
    mad = MAD_TO_SIGMA * median(np.abs(v - med), axis=0)
    scale = np.maximum(np.broadcast_to(np.asarray(sigma, dtype=float), med.shape), mad)
    scale = np.where(scale > 0, scale, np.inf)
    return np.abs(v - med) / scale


@dataclass
class ReRead:
    """One outlier and the reading that replaced it (recorded in the step's reading)."""

    instrument: str
    index: int
    was: list[float]
    deviation_sigma: float
    now: list[float] | None = None

    def record(self) -> dict:
        return {"instrument": self.instrument, "index": self.index, "was": self.was,
                "deviation_sigma": round(self.deviation_sigma, 2), "now": self.now}


@dataclass
class AgreeingReadings:
    """n readings of one quantity (d components) from one instrument, brought into agreement.

    ``reread(i)`` takes a fresh reading to replace reading i; ``settle()`` replaces outliers
    by fresh readings until every reading lies within ``K_READING`` sigma of the median, or
    raises Implausible after ``MAX_REREADS`` re-reads.
    """

    driver: object
    what: str
    sigma: np.ndarray | float
    reread: Callable[[int], Sequence[float]]
    values: list[list[float]] = field(default_factory=list)
    rereads: list[ReRead] = field(default_factory=list)

    def add(self, reading: Sequence[float]) -> None:
        self.values.append([float(x) for x in reading])

    def settle(self, k: float = K_READING, max_rereads: int = MAX_REREADS) -> np.ndarray:
        while True:
            dev = deviations(np.array(self.values), self.sigma).max(axis=1)
            bad = [int(i) for i in np.flatnonzero(dev > k)]
            if not bad:
                return np.array(self.values)
            i = max(bad, key=lambda j: dev[j])
            if len(self.rereads) >= max_rereads:
                med = median(np.array(self.values), axis=0)
                raise Implausible(
                    source_of(self.driver),
                    f"{self.what}: reading {i + 1} of {len(self.values)} "
                    f"{_fmt(self.values[i])} lies {dev[i]:.0f} sigma from the others' median "
                    f"{_fmt(med)} after {len(self.rereads)} re-reads "
                    f"(limit {k:g} sigma): the readings do not agree")
            rr = ReRead(str(getattr(self.driver, "name", "")), i, list(self.values[i]),
                        float(dev[i]))
            self.values[i] = [float(x) for x in self.reread(i)]
            rr.now = list(self.values[i])
            self.rereads.append(rr)
            note_reread(rr.record() | {"what": self.what})


def _fmt(v: ArrayLike) -> str:
    return "(" + ", ".join(f"{float(x):.7g}" for x in np.atleast_1d(v)) + ")"


# ----------------------------------------------------------------------------- known scatter


def tilt_scatter_arcsec(noise: NoiseSpec, times: Sequence[float]) -> float:
    """rms of the pier tilt about its mean over readings taken at ``times`` (the larger
    horizontal axis), arcsec: what a level or autocollimator reading moves by on its own."""
    t = np.asarray(times, dtype=float)
    if t.size < 2:
        return 0.0
    lag = t[:, None] - t[None, :]
    ee, nn, _ = noise.tilt_covariance(lag)
    ee0, nn0, _ = noise.tilt_covariance(0.0)
    out = 0.0
    for c, c0 in ((np.asarray(ee), float(ee0)), (np.asarray(nn), float(nn0))):
        var = c0 - 2.0 * c.mean(axis=1) + c.mean()  # each reading about the readings' mean
        out = max(out, float(np.sqrt(max(float(var.max()), 0.0))))
    return out / ARCSEC


def level_sigma_arcsec(noise: NoiseSpec, times: Sequence[float]) -> float:
    """One bubble-level reading's scatter about the median of readings at ``times``."""
    return math.hypot(noise.bubble_sigma / ARCSEC, tilt_scatter_arcsec(noise, times))


def autocollimator_sigma_deg(noise: NoiseSpec, times: Sequence[float],
                             zenith_deg: float) -> np.ndarray:
    """(azimuth, zenith) scatter of one autocollimator reading about the median, deg; the
    azimuth's noise across the line of sight is 1/sin(zenith) larger in angle."""
    s = math.hypot(noise.autocollimator_arcsec, tilt_scatter_arcsec(noise, times)) / 3600.0
    return np.array([s / max(math.sin(math.radians(zenith_deg)), 1e-3), s])
