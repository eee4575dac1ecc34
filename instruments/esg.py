"""Serial instruments of the ESG laboratory (report 004: strapdown ESG on a dividing head).

Protocols as in docs/esg.md (folded into docs/protocols.md, "ESG laboratory").

Data processor (two counters on two of the three pickoffs, 100 MHz counts; a processor
built with three counters, ``EsgParams.counters = 3``, reads all three at once):
  SEL <a> <b> [<c>]  counters A, B (and C) to pickoffs a, b (, c) (1..3, distinct;
                  c only with three counters)                                  -> OK
  REV <n>         revolutions summed per line, n in {1, 2, 4, 8, 10}           -> OK
  RUN <n>         run number printed in the lines, 0..9999999                  -> OK
  THR <volts>     HIT threshold 0.1..5                                         -> OK
  DISC <us>       pulse-width discriminator 2..24                              -> OK
  DELAY <us>      logic-line delay gate 20..2000                               -> OK
  TZERO           processor clock to 0 h                                       -> OK
  GO <k>          OK, then k data lines one every 0.0002 h (k 1..1000000)
  GO              OK, then data lines until HALT
  HALT            stop the stream (OK also when none runs)                     -> OK
  SET?            "<a> <b> <rev> <run> <thr> <disc> <delay>" (with a third pickoff
                  selected: "<a> <b> <c> <rev> ...")
  SCOPE? <k>      pickoff k's pulses on the scope: "<height V> <logic width> <line-1
                  width> <line-2 width> <logic-to-line-1 time>" (us), or "OFF"
The settings commands and TZERO are refused while a stream runs (ERR 16 busy); queries
are answered between the lines. A data line (Appendix A) is six 7-digit fields:
``time C1(p1) C1(p2) C1(p3) run period_sum``, time in 1e-5 h of the processor clock.
Dividing head: SPIN <deg> | STEP <deg> | SPIN? | STAT? (HOLD | MOVING) | SHIM <x> <y>
(the case re-shimmed on the adapter plate: the mirror along the spindle moved by x, y
arcsec on the theodolite's axes, |x|, |y| <= 120) | MOUNT <k> (the case set back on the
plate with mirror k, 1 or 2, along the spindle: mirror 1 with c2, c3 where they were,
mirror 2 with c3 where c2 was and c1 where c3 was; not yet shimmed) | MOUNT? (the mirror
along the spindle); SHIM and MOUNT answer ERR 16 while the spindle moves, ERR 19 with
the rotor spinning.
Turntable and tilt: AZ <deg> | TILT <deg> | AZ? | TILT? | LOCK | UNLOCK | STAT?
(HOLD | MOVING | LOCKED).
Theodolite: READ? -> "<x> <y>" arcsec.
Gyro control console: SPIN UP|OFF | DAMP ON|OFF | STAT? | SPEED? | LAMP <k> <percent>
(50..150 of the nominal lamp current) | LAMP? <k> | XLATE <k> <a> <b> (pickoff k translated
in its fixture: its line of sight moved a, b arcsec along the next two case axes, |a|,
|b| <= 120).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Generator
from typing import Any

import simpy

from instruments.base import ByteInstrument, InstrumentError, as_int
from instruments.base import as_real_in as _in_range
from sim.esg.processor import ProcessorSettings
from sim.esg.world import EsgWorld
from sim.rng import stream
from sim.timebase import seconds, ticks, ticks_ceil

LINE_HOURS = 0.0002  # one data line every 0.0002 h
LINE_TICKS = ticks(LINE_HOURS * 3600.0)  # 0.72 s, exact in ns
LINE_UNITS = 20  # 0.0002 h in the 1e-5 h units of the time field
WRAP = 10**7  # seven-digit fields
REVOLUTIONS = (1, 2, 4, 8, 10)
MAX_LINES = 1_000_000
BUSY = 16
SPINNING = 19  # the head refuses a shim with the rotor spinning
SHIM_MAX_ARCSEC = 120.0  # the adapter plate's shims: mirror 1 moved at most this far
XLATE_MAX_ARCSEC = 120.0  # the pickoff fixture's travel (line of sight, arcsec)

# what a garbled line may carry instead of a digit: printable non-digits (never a space,
# which would change the field count) and bytes a noisy line turns into
_NON_DIGITS = [bytes([c]) for c in b"?*#:;/=<>OlIZSB"] + [b"\xb3", b"\xff", b"\x8f"]


def _busy(what: str) -> InstrumentError:
    return InstrumentError(BUSY, f"busy: {what}")


def _pickoff(arg: str) -> int:
    return as_int(arg, "pickoff", 1, 3)


def _on_off(args: list[str], cmd: str, words: tuple[str, str]) -> bool:
    w = args[0].upper()
    if w not in words:
        raise InstrumentError(12, f"{cmd} takes {words[0]} or {words[1]}, got '{args[0][:10]}'")
    return w == words[0]


# --------------------------------------------------------------------------- processor


class DataProcessor(ByteInstrument):
    """The pickoff data processor and its line printer (report 004, Appendix A)."""

    ident = "ESG-LAB,DATA-PROCESSOR,0,1.0"

    def __init__(self, name: str, world: EsgWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.pickoffs: tuple[int, ...] = (2, 3)
        self.counters = int(world.p.counters)
        self.revolutions = 10
        self.run = 0
        self.settings = ProcessorSettings()
        self.t_zero = int(self.env.now)  # ticks; the processor clock reads hours since then
        self.corrupt_every = 0  # fault injection: every n-th line gets one character wrong
        self.lines_emitted = 0
        self.lines_corrupted = 0
        self._rng = stream(world.seed, "esg", "corrupt")
        self._stream: simpy.Process | None = None
        for usage, action in (
            # a two-counter processor keeps its two-pickoff usage (a third is ERR 11)
            ("SEL <a> <b> [<c>]" if self.counters >= 3 else "SEL <a> <b>", self._sel),
            ("REV <n>", self._rev),
            ("RUN <n>", self._run_number),
            ("THR <volts>", lambda a: self._setting("THR", "threshold_v", a[0], "threshold",
                                                    0.1, 5.0)),
            ("DISC <us>", lambda a: self._setting("DISC", "min_width_us", a[0],
                                                  "discriminator width", 2.0, 24.0)),
            ("DELAY <us>", lambda a: self._setting("DELAY", "logic_delay_us", a[0],
                                                   "logic delay", 20.0, 2000.0)),
            ("TZERO", self._tzero),
            ("GO [<k>]", self._go),
            ("HALT", self._halt),
            ("SET?", self._set_q),
            ("SCOPE? <k>", self._scope),
        ):
            self.define(usage, action)

    def _emit_line(self, data: bytes) -> None:
        ByteInstrument._emit(self, data)

    # ----- protocol -----
    @property
    def streaming(self) -> bool:
        return self._stream is not None and self._stream.is_alive

    def _settable(self, cmd: str) -> None:
        if self.streaming:
            raise _busy(f"data stream running, HALT before {cmd}")

    def clock_hours(self) -> float:
        """The processor clock, hours since TZERO."""
        return seconds(int(self.env.now) - self.t_zero) / 3600.0

    def _scope(self, args: list[str]) -> str:
        k = _pickoff(args[0])
        sc = self.world.scope(k)
        if sc is None:
            return "OFF"
        w = sc["widths_us"]
        return (f"{sc['height_v']:.2f} {w[0]:.1f} {w[1]:.1f} {w[2]:.1f} "
                f"{sc['logic_to_line_us']:.1f}")

    def _sel(self, args: list[str]) -> str:
        a = as_int(args[0], "pickoff a", 1, 3)
        b = as_int(args[1], "pickoff b", 1, 3)
        sel = [a, b]
        if len(args) > 2:  # only a three-counter processor's usage admits a third
            sel.append(as_int(args[2], "pickoff c", 1, 3))
        if len(set(sel)) < len(sel):
            raise InstrumentError(12, f"pickoffs must be distinct, got {' '.join(map(str, sel))}")
        self._settable("SEL")
        self.pickoffs = tuple(sel)
        return "OK"

    def _rev(self, args: list[str]) -> str:
        n = as_int(args[0], "revolutions", 1, 10)
        if n not in REVOLUTIONS:
            raise InstrumentError(
                12, f"revolutions must be one of {', '.join(map(str, REVOLUTIONS))}, got {n}"
            )
        self._settable("REV")
        self.revolutions = n
        return "OK"

    def _run_number(self, args: list[str]) -> str:
        n = as_int(args[0], "run number", 0, WRAP - 1)
        self._settable("RUN")
        self.run = n
        return "OK"

    def _setting(self, cmd: str, field: str, x: str, what: str, lo: float, hi: float) -> str:
        v = _in_range(x, what, lo, hi)
        self._settable(cmd)
        self.settings = dataclasses.replace(self.settings, **{field: v})
        return "OK"

    def _tzero(self, _: list[str]) -> str:
        self._settable("TZERO")
        self.t_zero = int(self.env.now)
        return "OK"

    def _go(self, args: list[str]) -> str:
        k = as_int(args[0], "line count", 1, MAX_LINES) if args else None
        if self.streaming:
            raise _busy("data stream already running")
        self._stream = self.env.process(self._lines(k, self.replies_queued + 1))
        return "OK"

    def _halt(self, _: list[str]) -> str:
        if self._stream is not None and self._stream.is_alive:
            self._stream.interrupt("HALT")
        self._stream = None
        return "OK"

    def _set_q(self, _: list[str]) -> str:
        s = self.settings
        return (f"{' '.join(map(str, self.pickoffs))} {self.revolutions} {self.run} "
                f"{s.threshold_v:g} {s.min_width_us:g} {s.logic_delay_us:g}")

    # ----- the stream -----
    def _first_index(self) -> int:
        """Grid index of the first line that leaves REV revolutions of acquisition after
        the command (REV + 1 line-1 trailing edges: the period sum spans REV turns)."""
        rps = float(self.world.console_status()["spin_rps"])
        rps = rps if rps > 1.0 else float(self.world.p.spin_rps)  # a stopped rotor: nominal
        earliest = int(self.env.now) + ticks_ceil((self.revolutions + 1) / rps)
        return max(0, -((self.t_zero - earliest) // LINE_TICKS))  # ceiling division

    def _lines(self, k: int | None, ok_seq: int) -> Generator[simpy.Event, Any, None]:
        a, b, *c = self.pickoffs
        rev, run, settings = self.revolutions, self.run, self.settings
        n = self._first_index()
        done = 0
        try:
            while k is None or done < k:
                t = self.t_zero + n * LINE_TICKS
                yield self.env.timeout(t - self.env.now)
                counts = self.world.data_line(seconds(t), a, b, rev, settings,
                                              c[0] if c else None)
                line = self.format_line(n, counts.c1, run, counts.period_sum)
                while self.replies_done < ok_seq:  # the GO's OK leaves (or is cleared) first
                    yield self._done_event
                self.lines_emitted += 1
                if self.corrupt_every > 0 and self.lines_emitted % self.corrupt_every == 0:
                    line = self._corrupt(line, (a, b))
                self._emit_line(line)
                n += 1
                done += 1
        except simpy.Interrupt:
            pass
        except Exception as e:  # noqa: BLE001 - a fault of the simulation: the stream ends
            self.internal_error("data stream (GO)", e)  # on the error queue

    @staticmethod
    def format_line(n: int, c1: dict[int, int], run: int, period_sum: int) -> bytes:
        """Appendix-A line for grid index ``n`` (time = 20 n units of 1e-5 h)."""
        fields = [(n * LINE_UNITS) % WRAP, *(int(c1.get(p, 0)) % WRAP for p in (1, 2, 3)),
                  run % WRAP, int(period_sum) % WRAP]
        return (" ".join(f"{v:07d}" for v in fields) + "\n").encode("ascii")

    def _corrupt(self, line: bytes, selected: tuple[int, int]) -> bytes:
        """One character of a C1 or period field replaced, in a high-order position.

        Corruptions alternate: a non-digit, then a different digit. The changed digit is
        always one the format checks catch (a selected C1 pushed to or above the period
        sum, or the period sum pushed to or below a selected C1): an Appendix-A line has
        no checksum, so a plausible wrong digit could not be caught by anyone.
        """
        rng = self._rng
        fields = line.rstrip(b"\n").split(b" ")
        targets = [selected[0], selected[1], 5]  # C1 of a, C1 of b, period sum
        self.lines_corrupted += 1
        if self.lines_corrupted % 2 == 0:
            cands = self._digit_candidates(fields, selected)
            if cands:
                f, pos, d = cands[int(rng.integers(len(cands)))]
                fields[f] = fields[f][:pos] + bytes([d]) + fields[f][pos + 1:]
                return b" ".join(fields) + b"\n"
        f = targets[int(rng.integers(3))]
        pos = int(rng.integers(2))
        ch = _NON_DIGITS[int(rng.integers(len(_NON_DIGITS)))]
        fields[f] = fields[f][:pos] + ch + fields[f][pos + 1:]
        return b" ".join(fields) + b"\n"

    @staticmethod
    def _digit_candidates(fields: list[bytes], selected: tuple[int, int]
                          ) -> list[tuple[int, int, int]]:
        """(field, position, digit) of each one-digit change the format checks catch."""
        out = []
        for f in (*selected, 5):
            for pos in (0, 1):
                for d in b"0123456789":
                    if d == fields[f][pos]:
                        continue
                    new = list(fields)
                    new[f] = new[f][:pos] + bytes([d]) + new[f][pos + 1:]
                    period = int(new[5])
                    c1 = [int(new[p]) for p in selected]
                    if period == 0 or any(c >= period for c in c1):
                        out.append((f, pos, d))
        return out


# --------------------------------------------------------------------------- dividing head


class DividingHead(ByteInstrument):
    ident = "ESG-LAB,DIVIDING-HEAD,0,1.0"

    def __init__(self, name: str, world: EsgWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.define("SPIN <deg>", lambda a: self._move(
            _in_range(a[0], "spindle angle", 0.0, 360.0, hi_open=True)))
        self.define("STEP <deg>", self._step)
        self.define("SPIN?", lambda _: f"{world.head_reading_deg() % 360.0:.5f}")
        self.define("STAT?", lambda _: "MOVING" if world.head_moving() else "HOLD")
        self.define("SHIM <x> <y>", self._shim)
        self.define("MOUNT <k>", self._mount)
        self.define("MOUNT?", lambda _: str(world.case.mirror_on_spindle))

    def _shim(self, args: list[str]) -> str:
        x = _in_range(args[0], "shim x", -SHIM_MAX_ARCSEC, SHIM_MAX_ARCSEC)
        y = _in_range(args[1], "shim y", -SHIM_MAX_ARCSEC, SHIM_MAX_ARCSEC)
        self._at_rest("shim")
        self.world.shim(x, y)
        return "OK"

    def _mount(self, args: list[str]) -> str:
        k = as_int(args[0], "mirror", 1, 2)
        self._at_rest("remount")
        self.world.remount(k)
        return "OK"

    def _at_rest(self, what: str) -> None:
        """Refused while the spindle moves (ERR 16) or the rotor spins (ERR 19)."""
        if self.world.head_moving():
            raise _busy("spindle still moving")
        if self.world.console_status()["spin_rps"] > 0.0:
            raise InstrumentError(SPINNING, f"rotor spinning: {what} the case at rest")

    def _move(self, deg: float) -> str:
        if self.world.head_moving():
            raise _busy("spindle still moving")
        self.world.head_move(round(deg, 5) % 360.0)
        return "OK"

    def _step(self, args: list[str]) -> str:
        step = _in_range(args[0], "spindle step", -360.0, 360.0)
        return self._move((self.world.head_reading_deg() + step) % 360.0)


# --------------------------------------------------------------------------- turntable


class Turntable(ByteInstrument):
    ident = "ESG-LAB,TURNTABLE-TILT,0,1.0"

    def __init__(self, name: str, world: EsgWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.locked = False
        for usage, action in (
            ("AZ <deg>", self._az),
            ("TILT <deg>", self._tilt),
            ("AZ?", lambda _: f"{world.table_reading_deg()[0] % 360.0:.4f}"),
            ("TILT?", lambda _: f"{world.table_reading_deg()[1]:.4f}"),
            ("LOCK", self._lock),
            ("UNLOCK", self._unlock),
            ("STAT?", self._stat),
        ):
            self.define(usage, action)

    def _az(self, args: list[str]) -> str:
        deg = _in_range(args[0], "azimuth", 0.0, 360.0, hi_open=True)
        if self.world.table_moving():
            raise _busy("table still moving")
        if self.locked:
            raise InstrumentError(18, "azimuth locked: UNLOCK first")
        self.world.table_move(azimuth_deg=round(deg, 4) % 360.0)
        return "OK"

    def _tilt(self, args: list[str]) -> str:
        lim = float(self.world.p.mount.tilt_limit_deg)
        deg = _in_range(args[0], "tilt", -lim, lim)
        if self.world.table_moving():
            raise _busy("table still moving")
        self.world.table_move(tilt_deg=round(deg, 4))
        return "OK"

    def _lock(self, _: list[str]) -> str:
        if self.world.table_moving():
            raise _busy("table still moving")
        self.locked = True
        return "OK"

    def _unlock(self, _: list[str]) -> str:
        self.locked = False
        return "OK"

    def _stat(self, _: list[str]) -> str:
        if self.world.table_moving():
            return "MOVING"
        return "LOCKED" if self.locked else "HOLD"


# --------------------------------------------------------------------------- theodolite


class Theodolite(ByteInstrument):
    ident = "ESG-LAB,THEODOLITE,0,1.0"

    def __init__(self, name: str, world: EsgWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.define("READ?", self._read)

    def _read(self, _: list[str]) -> str:
        x, y = self.world.theodolite_arcsec()
        return f"{x:.2f} {y:.2f}"


# --------------------------------------------------------------------------- console


class GyroConsole(ByteInstrument):
    ident = "ESG-LAB,GYRO-CONSOLE,0,1.0"

    def __init__(self, name: str, world: EsgWorld, latency_s: float) -> None:
        super().__init__(name, world.env, latency_s)
        self.world = world
        self.define("SPIN UP|OFF", self._spin)
        self.define("DAMP ON|OFF", self._damp)
        self.define("STAT?", self._stat)
        self.define("SPEED?", lambda _: f"{world.console_status()['spin_rps']:.2f}")
        self.define("LAMP <k> <percent>", self._lamp)
        self.define("LAMP? <k>", lambda a: f"{100.0 * world.lamp(_pickoff(a[0])):.1f}")
        self.define("XLATE <k> <a> <b>", self._translate)

    def _translate(self, args: list[str]) -> str:
        k = _pickoff(args[0])
        a = _in_range(args[1], "translation a", -XLATE_MAX_ARCSEC, XLATE_MAX_ARCSEC)
        b = _in_range(args[2], "translation b", -XLATE_MAX_ARCSEC, XLATE_MAX_ARCSEC)
        self.world.translate_pickoff(k, a, b)
        return "OK"

    def _lamp(self, args: list[str]) -> str:
        k = _pickoff(args[0])
        pct = _in_range(args[1], "lamp current", 50.0, 150.0)
        self.world.set_lamp(k, pct / 100.0)
        return "OK"

    def _spin(self, args: list[str]) -> str:
        if _on_off(args, "SPIN", ("UP", "OFF")):
            self.world.spin_up()
        else:
            self.world.spin_off()
        return "OK"

    def _damp(self, args: list[str]) -> str:
        self.world.set_damping(_on_off(args, "DAMP", ("ON", "OFF")))
        return "OK"

    def _stat(self, _: list[str]) -> str:
        s = self.world.console_status()
        return (f"SUSP {int(bool(s['suspended']))} SPIN {s['spin_rps']:.2f} "
                f"DAMP {int(bool(s['damping']))} VAC {s['pressure_torr']:.1E}")


__all__ = ["DataProcessor", "DividingHead", "GyroConsole", "Theodolite", "Turntable"]
