"""laboratory.isu.display: the live check-sheet ticks of `station day` and `station align`.
Piped (a plain console) a line that fits is written as it stands (issue 17: rich's
rendering cost most of a tick); the output is what rich itself prints for the same line,
whatever the width, the words (brackets included) and the wrapping."""

from __future__ import annotations

import io
import random

import pytest
from rich.console import Console

from laboratory.isu.display import DayDisplay, shown_console

WORDS = ["Set", "phi1", "=", "90", "deg", "[red]", "(project", "addition)", "T^BRm", "\u2713",
         "counters", "1-4", "[dim]x[/]", "\u5bbd\u5b57\u7b26", "x" * 70, "S1^T,", "ok"]


def _events(rng: random.Random) -> list[dict]:
    evs: list[dict] = []
    t = 0.0
    for _ in range(40):
        if rng.random() < 0.15:
            evs.append({"kind": "sheet_start", "chart": rng.choice(["I-1", "II-6", "III-12"]),
                        "title": " ".join(rng.choices(WORDS, k=rng.randint(1, 12)))})
        t += rng.uniform(0.0, 900.0)
        evs.append({"kind": "step", "t_sim": t, "chart": rng.choice(["I-2", "II-15", "III-4"]),
                    "step": rng.choice(["1", "5a", "9/m1", "6/g1/-15"]),
                    "text": " ".join(rng.choices(WORDS, k=rng.randint(0, 25)))})
        if rng.random() < 0.05:
            evs.append({"kind": "note", "event": "start"})  # not shown
    return evs


@pytest.mark.parametrize("seed", range(6))
def test_piped_ticks_are_what_rich_prints(seed: int) -> None:
    rng = random.Random(seed)
    width = rng.randint(20, 200)
    evs = _events(rng)
    outs = []
    for shortcut in (True, False):
        buf = io.StringIO()
        with DayDisplay(Console(file=buf, width=width)) as display:
            assert display.plain_width == width
            if not shortcut:  # every line through console.print: the reference
                display.plain_width = None
            for ev in evs:
                display(ev)
        outs.append(buf.getvalue())
    out, ref = outs
    assert out == ref
    assert out.count("\u2713 ") >= sum(ev["kind"] == "step" for ev in evs)
    assert "[red]" in out or all("[red]" not in ev.get("text", "") for ev in evs)


def test_terminal_ticks_keep_their_colours() -> None:
    buf = io.StringIO()
    console = Console(file=buf, width=100, force_terminal=True, color_system="truecolor")
    with DayDisplay(console) as display:
        display({"kind": "step", "t_sim": 3600.0, "chart": "II-6", "step": "1",
                 "text": "Resolver settings available"})
    out = buf.getvalue()
    assert "\x1b[" in out and "Resolver settings available" in out and "1.000 h" in out


def test_quiet_shows_nothing() -> None:
    buf = io.StringIO()
    with DayDisplay(shown_console(Console(file=buf, width=80), quiet=True)) as display:
        display({"kind": "step", "t_sim": 1.0, "chart": "I-1", "step": "1", "text": "x"})
    assert buf.getvalue() == ""


def test_quiet_console_shows_nothing() -> None:
    """A console made quiet (laboratory.virtual's) prints nothing, even unasked to be."""
    buf = io.StringIO()
    with DayDisplay(Console(file=buf, width=80, quiet=True)) as display:
        display({"kind": "sheet_start", "chart": "I-1", "title": "Laboratory turn-on"})
        display({"kind": "step", "t_sim": 1.0, "chart": "I-1", "step": "1", "text": "x"})
    assert buf.getvalue() == ""


@pytest.mark.parametrize("plain", [True, False])
def test_a_lost_reader_quiets_the_display_and_the_run_goes_on(
        plain: bool, capsys: pytest.CaptureFixture[str]) -> None:
    """The pipe's reader goes after the first line: the next tick meets a broken pipe,
    written straight (plain) or through rich (whose own answer ends the process); the
    display goes quiet, the descriptor writes to /dev/null now, and stderr says so once."""
    import os

    from laboratory.console import NOTE, StationConsole

    r, w = os.pipe()
    f = os.fdopen(w, "w", buffering=1)
    console = StationConsole(file=f, width=80)
    evs = _events(random.Random(3))
    steps = [ev for ev in evs if ev["kind"] == "step"]
    with DayDisplay(console) as display:
        if not plain:
            display.plain_width = None
        display(steps[0])
        assert os.read(r, 4096).decode().startswith("  \u2713")
        os.close(r)
        for ev in evs:  # the first of these meets the broken pipe; none raises
            display(ev)
        assert display.quiet and console.reader_gone
        console.print("the tables and the record's path")  # to /dev/null now: no error
    f.write("the flush at exit\n")
    f.close()
    assert capsys.readouterr().err.count(NOTE) == 1
