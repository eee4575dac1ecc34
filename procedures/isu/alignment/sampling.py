"""IEU data collection for alignment (Flow Diagrams 16 and 19).

The IEU latches and clears its registers every ``period_ticks`` S2^T pulses and sends the
sample; the computer adds consecutive samples until Delta t has elapsed (an interval), and
repeats until K intervals are held. Nothing is lost between samples (the registers
telescope) or between intervals (an interval is a whole number of samples). Delta t of each
interval is S2^T times the sum of its samples' timer counts, the IEU's own measure of it.

Every sample is checked: consecutive sequence numbers (the driver; in recover mode a lost
sample is asked for again with RESEND), no register overflow (which stops the collection:
the period is too long) and the timer count equal to the commanded period (a sample that is
not one whole period means the IEU restarted or a frame was altered).

Then the counts themselves: the registers telescope and the lab is at rest, so each
signal's count per sample stays within its quantization (a count is a difference of two
floors) of its neighbours' running median. A sample beyond ``K_READING`` sigma of it (an
altered frame the link did not catch, or a disturbance) spoils the record, and the record
is never summed with it: ``collect_checked`` takes the record again (at most ``retakes``
times, each recorded) and then stops naming the IEU and the sample.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from procedures.isu import plausibility as pl
from procedures.isu.calibration.noise_spec import NoiseSpec
from procedures.medians import median
from station.errors import DriverError

if TYPE_CHECKING:
    from station.drivers.isu import IsuDrivers

SIGNALS = ("gyro 1", "gyro 2", "gyro 3", "A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2")
NEIGHBOURS = 31  # samples in the running median a count is compared with


RAW_COLUMNS = ("seq", "t_s", "timer", "flags", "gyro1", "gyro2", "gyro3",
               "A1S1", "A1S2", "A2S1", "A2S2", "A3S1", "A3S2")


@dataclass(frozen=True)
class RawSamples:
    """Every IEU sample of a record as the driver returned it (n rows), before summing:
    kept so the record can export them; the alignment itself uses only the sums."""

    seq: np.ndarray  # n sequence numbers
    t: np.ndarray  # n link times of the timer frames, s
    timer: np.ndarray  # n timer counts (S2^T pulses)
    flags: np.ndarray  # n flag words
    gyro: np.ndarray  # n x 3 net pulses
    strings: np.ndarray  # n x 6 string counts (A1S1, ..., A3S2)

    def rows(self) -> list[dict]:
        """One dict per sample, keys ``RAW_COLUMNS``."""
        cols = (self.seq.astype(np.int64).tolist(), self.t.astype(float).tolist(),
                self.timer.astype(np.int64).tolist(), self.flags.astype(np.int64).tolist(),
                *self.gyro.astype(np.int64).T.tolist(), *self.strings.astype(np.int64).T.tolist())
        return [dict(zip(RAW_COLUMNS, vals, strict=True)) for vals in zip(*cols, strict=True)]


@dataclass
class IeuRecord:
    """K intervals of summed IEU samples."""

    period_ticks: int
    samples_per_interval: int
    s2_t: float  # S2^T, s per timer pulse
    gyro: np.ndarray  # K x 3 net pulses
    strings: np.ndarray  # K x 6 string counts (A1S1, A1S2, ..., A3S2)
    timer: np.ndarray  # K timer counts
    t_start: float  # link time of the latch that opens the data, s
    first_seq: int
    last_seq: int
    recoveries: list[dict] = field(default_factory=list)
    garbled: int = 0
    outliers: list[dict] = field(default_factory=list)  # samples off their neighbours
    retakes: list[dict] = field(default_factory=list)  # earlier records refused
    raw: RawSamples | None = None  # the samples summed, as received (for the record's CSV)

    @property
    def K(self) -> int:
        return int(self.timer.size)

    @property
    def dt(self) -> np.ndarray:
        """Interval lengths Delta t = S2^T (Sigma n2^T), s."""
        return self.s2_t * self.timer.astype(float)

    @property
    def t_end(self) -> float:
        return self.t_start + float(np.sum(self.dt))

    def summary(self) -> dict:
        return {
            "K": self.K,
            "period_ticks": self.period_ticks,
            "samples_per_interval": self.samples_per_interval,
            "samples": self.K * self.samples_per_interval,
            "seq": [self.first_seq, self.last_seq],
            "t_start_s": self.t_start,
            "t_end_s": self.t_end,
            "dt_s": [float(self.dt.min()), float(self.dt.max())],
            "recovered_samples": self.recoveries,
            "garbled_frames_ignored": self.garbled,
            **({"retakes": self.retakes} if self.retakes else {}),
        }


def count_sigma(noise: NoiseSpec) -> float:
    """One sample count's scatter about its neighbours' running median, counts: the count
    and the median each carry the quantization of a difference of two floors (the gyros'
    and strings' own noise over a sample is far below a count)."""
    return float(np.sqrt(2.0 * noise.count_quantization_var))


def sample_deviations(counts: np.ndarray, noise: NoiseSpec) -> tuple[np.ndarray, np.ndarray]:
    """(|count - running median of its NEIGHBOURS| in sigma, the medians), n x 9."""
    n = counts.shape[0]
    w = min(NEIGHBOURS, n if n % 2 else n - 1)
    if w < 3:
        return np.zeros(counts.shape), counts.astype(float)
    half = w // 2
    padded = np.pad(counts.astype(float), ((half, half), (0, 0)), mode="edge")
    med = median(np.lib.stride_tricks.sliding_window_view(padded, w, axis=0), axis=-1)
    return np.abs(counts - med) / count_sigma(noise), med


def sample_outliers(counts: np.ndarray, seqs: np.ndarray, noise: NoiseSpec,
                    k: float = pl.K_READING) -> list[dict]:
    """Samples whose count of some signal lies beyond ``k`` sigma of the running median of
    its ``NEIGHBOURS`` (n x 9 counts: gyros 1-3, then the six strings)."""
    dev, med = sample_deviations(counts, noise)
    out = []
    for i, j in zip(*np.nonzero(dev > k), strict=True):
        out.append({"seq": int(seqs[i]), "signal": SIGNALS[j], "count": int(counts[i, j]),
                    "neighbours_median": float(med[i, j]), "deviation_sigma": float(dev[i, j])})
    return out


def collect(
    st: IsuDrivers,
    period_ticks: int,
    samples_per_interval: int,
    K: int,
    recover: bool = True,
    timeout: float = 5.0,
    s2: float | None = None,
    noise: NoiseSpec | None = None,
) -> IeuRecord:
    """Sample the IEU and sum ``samples_per_interval`` samples into each of K intervals.

    ``s2``: S2^T in seconds (as turn-on recorded it; read from the oscillator if not given).
    The samples whose timer is not the period, or whose counts disagree with their
    neighbours, are listed in ``outliers`` (``collect_checked`` refuses such a record).
    """
    if period_ticks < 1 or samples_per_interval < 1 or K < 1:
        raise ValueError("period, samples per interval and K must be positive")
    if s2 is None:
        s2 = st.oscillator.s_t(2)
    n = K * samples_per_interval
    gyro = np.zeros((n, 3), dtype=np.int64)
    strings = np.zeros((n, 6), dtype=np.int64)
    timer = np.zeros(n, dtype=np.int64)
    stamps = np.zeros(n)
    seqs = np.zeros(n, dtype=np.int64)
    flags = np.zeros(n, dtype=np.int64)
    bad_timer: list[dict] = []
    st.ieu.start(period_ticks, recover=recover)
    try:
        first = None
        for i in range(n):
            s = st.ieu.next_sample(timeout=timeout)
            if first is None:
                first = s
            if s.flags & 1:
                raise pl.Implausible(pl.source_of(st.ieu), f"register overflow in sample "
                                     f"{s.seq}: shorten the period")
            if s.timer != period_ticks:  # not one whole period: a restart or an altered frame
                bad_timer.append({"seq": s.seq, "signal": "timer", "count": int(s.timer),
                                  "neighbours_median": float(period_ticks),
                                  "deviation_sigma": None})
            gyro[i] = s.gyro
            strings[i] = s.accel
            timer[i] = s.timer
            stamps[i] = s.t
            seqs[i] = s.seq
            flags[i] = s.flags
        last = s
    finally:
        recoveries = list(st.ieu.recoveries)
        garbled = st.ieu.garbled
        try:
            st.ieu.stop()
        except DriverError:
            pass  # the error being raised (if any) is the one to report
    assert first is not None
    # A sample's frames leave at its closing latch, so each stamp less the timer pulses so
    # far dates the opening latch; a resent sample's stamp is late: take the earliest.
    t_start = float(np.min(stamps - s2 * np.cumsum(timer)))
    shape = (K, samples_per_interval)
    return IeuRecord(
        period_ticks=period_ticks,
        samples_per_interval=samples_per_interval,
        s2_t=s2,
        gyro=gyro.reshape(*shape, 3).sum(axis=1),
        strings=strings.reshape(*shape, 6).sum(axis=1),
        timer=timer.reshape(shape).sum(axis=1),
        t_start=float(t_start),
        first_seq=first.seq,
        last_seq=last.seq,
        recoveries=recoveries,
        garbled=garbled,
        outliers=bad_timer + sample_outliers(np.hstack((gyro, strings)), seqs,
                                             noise or NoiseSpec.model_validate({})),
        raw=RawSamples(seqs, stamps, timer, flags, gyro, strings),
    )


def collect_checked(st: IsuDrivers, period_ticks: int, samples_per_interval: int, K: int,
                    recover: bool, s2: float, noise: NoiseSpec, retakes: int,
                    timeout: float = 5.0) -> IeuRecord:
    """``collect``, refusing a record with samples off their neighbours: it is taken again
    (at most ``retakes`` times; each refused record's outliers are kept in ``retakes``),
    then the step stops naming the IEU and the samples."""
    refused: list[dict] = []
    while True:
        rec = collect(st, period_ticks, samples_per_interval, K, recover, timeout, s2, noise)
        if not rec.outliers:
            rec.retakes = refused
            return rec
        refused.append({"seq": [rec.first_seq, rec.last_seq], "outliers": rec.outliers[:5]})
        if len(refused) > retakes:
            o = rec.outliers[0]
            what = ("not one whole period" if o["signal"] == "timer"
                    else f"{o['deviation_sigma']:.0f} sigma")
            raise pl.Implausible(
                pl.source_of(st.ieu),
                f"sample {o['seq']}: {o['signal']} counted {o['count']} where its neighbours "
                f"count {o['neighbours_median']:g} ({what}; "
                f"{len(rec.outliers)} such count(s) in this record, {len(refused)} record(s) "
                "taken): altered frames or a disturbance; the record is not used")
