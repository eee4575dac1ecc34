"""One dividing-head setting's data: five processor lines, checked and averaged.

The report's laboratory printed five lines per setting and threw out lines whose C1 or
count ratio stood far from the others (Readout Test Results); so do we, after the
driver's format checks. A mis-gated count (an arc mark past the discriminator) lands
anywhere, while good lines agree to about 1e-5, so we keep the largest group of lines that
agree with one another: that survives even when most of a setting's lines are hit, where
a median would not. Each rejected line keeps its reason for the journal.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from station.drivers.esg import BadLine, DataLine, ProcessorDriver
from station.errors import CheckFailed

AGREE = 5e-5  # count ratio; about 5 times the line-to-line scatter (13 arcsec)


@dataclass
class Setting:
    """Mean count ratios of one setting and what went into them."""

    pickoffs: tuple[int, ...]  # two, or three on a three-counter processor
    t_s: float  # mean time of the lines used, processor clock, s
    cr: dict[int, float | None]  # None: the pickoff is off the pattern
    times_s: list[float] = field(default_factory=list)
    line_cr: dict[int, list[float]] = field(default_factory=dict)
    rejected: list[str] = field(default_factory=list)
    # every line the processor printed for the setting, as received (Appendix A, Table
    # A-1), rejected ones included, in order; "" for a line that never came
    lines: list[str] = field(default_factory=list)
    # mean 100 MHz count over a used line's revolutions (the spin period's measure; not
    # journaled: step 3 compares it between its own readings); 0.0 when not known
    period_sum: float = 0.0

    def reading(self) -> dict:
        """What the journal keeps of the setting (enough to reduce again)."""
        return {"pickoffs": list(self.pickoffs), "t_s": self.t_s,
                "cr": {str(k): v for k, v in self.cr.items()},
                "times_s": self.times_s,
                "line_cr": {str(k): v for k, v in self.line_cr.items()},
                "rejected": self.rejected, "lines": self.lines}

    def ratio(self, pickoff: int) -> float:
        """A pickoff's mean count ratio; a failed check when the pickoff is off the pattern."""
        v = self.cr[pickoff]
        if v is None:
            raise CheckFailed(f"pickoff {pickoff} is off the pattern (setting at "
                              f"t = {self.t_s:.1f} s)")
        return v

    @classmethod
    def from_reading(cls, d: dict) -> Setting:
        """The setting back from its journal form (``reading``)."""
        return cls(tuple(d["pickoffs"]), d["t_s"],
                   {int(k): v for k, v in d["cr"].items()}, list(d["times_s"]),
                   {int(k): list(v) for k, v in d["line_cr"].items()},
                   list(d["rejected"]), list(d.get("lines", [])))


class TooFewLines(CheckFailed):
    """Too few of the processor's data lines agree to give a reading (a failed check)."""


def _cr(line: DataLine, p: int) -> float | None:
    if line.c1[p - 1] == 0:
        return None
    return line.count_ratio(p)


def agreeing(rows: list[list[float]], tol: float = AGREE) -> list[bool]:
    """The largest group of lines within ``tol`` of one line in every value (ties: the
    tighter group); True for the lines kept."""
    best: tuple[int, float, list[bool]] | None = None
    for r in rows:
        keep = [all(abs(a - b) <= tol for a, b in zip(q, r, strict=True)) for q in rows]
        spread = sum(max(abs(a - b) for a, b in zip(q, r, strict=True)) if q else 0.0
                     for q, k in zip(rows, keep, strict=True) if k)
        n = sum(keep)
        if best is None or n > best[0] or (n == best[0] and spread < best[1]):
            best = (n, spread, keep)
    return best[2] if best else []


def read_setting(proc: ProcessorDriver, pickoffs: tuple[int, ...], n_lines: int = 5,
                 min_lines: int = 3, attempts: int = 3, agree: float = AGREE) -> Setting:
    """Select two pickoffs (three on a three-counter processor), take ``n_lines`` lines,
    reject bad ones (``agree``: the count-ratio agreement kept), average the rest."""
    proc.select(*pickoffs)
    rejected: list[str] = []
    printed: list[str] = []
    for _ in range(attempts):
        got = proc.lines(n_lines)
        printed.extend(ln.raw for ln in got)
        good: list[DataLine] = []
        for ln in got:
            if isinstance(ln, BadLine):
                rejected.append(f"{ln.reason}: {ln.raw!r}")
            else:
                good.append(ln)
        # the pickoffs on the pattern in every line, with their ratios line by line
        crs = {p: [_cr(ln, p) for ln in good] for p in pickoffs}
        on = {p: [v for v in vals if v is not None] for p, vals in crs.items()
              if vals and None not in vals}
        keep = agreeing([[on[p][i] for p in pickoffs if p in on] for i in range(len(good))],
                        agree)
        for i, k in enumerate(keep):
            if not k:
                rejected.append(f"count ratio off the setting's agreeing lines: "
                                f"{good[i].raw!r}")
        used = [ln for ln, k in zip(good, keep, strict=True) if k]
        if len(used) >= min_lines:
            times = [ln.time_hr * 3600.0 for ln in used]
            line_cr = {p: [ln.count_ratio(p) for ln in used] for p in pickoffs if p in on}
            cr = {p: (sum(v) / len(v) if p in line_cr else None)
                  for p, v in ((p, line_cr.get(p, [])) for p in pickoffs)}
            return Setting(pickoffs, sum(times) / len(times), cr, times, line_cr, rejected,
                           printed, sum(ln.period_sum for ln in used) / len(used))
    raise TooFewLines(f"fewer than {min_lines} usable lines of {n_lines} in {attempts} "
                      f"attempts; rejected: {'; '.join(rejected[-3:])}")
