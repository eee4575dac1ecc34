"""The live display of `station day` and `station align`: check-sheet ticks as they happen
and a progress bar in simulated time. When the console's reader goes away
(laboratory.console) the display goes quiet and the run goes on."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rich.cells import cell_len
from rich.console import Console
from rich.text import Text

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

EXPECTED_SIM_S = 9.0 * 3600.0  # for the progress bar only


class DayDisplay:
    """Check-sheet ticks as they happen, and a progress bar in simulated time."""

    def __init__(self, console: Console, quiet: bool = False) -> None:
        self.console = console
        self.quiet = quiet or console.quiet  # a quiet console shows nothing, written or not
        self.progress: Progress | None = None
        self.task: TaskID | None = None
        if not self.quiet:  # rich.progress only for a bar shown (10 ms of imports, issue 17)
            from rich.progress import BarColumn, Progress, TextColumn

            self.progress = Progress(
                TextColumn("[bold]{task.description}"), BarColumn(),
                TextColumn("{task.fields[sim]}"), console=console, transient=True,
            )
            self.task = self.progress.add_task("calibration day", total=EXPECTED_SIM_S,
                                               sim="")
        # piped or redirected: no colours and no bar, so a line that fits is the text itself
        self.plain_width = None if console.is_terminal else console.width

    def __enter__(self) -> DayDisplay:
        if not self.quiet and self.progress is not None:
            self.progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if not self.quiet and self.progress is not None:
            try:
                self.progress.stop()
            except BrokenPipeError:
                self.console.on_broken_pipe()

    def __call__(self, ev: dict) -> None:
        if self.quiet:
            return
        try:
            self._show(ev)
        except BrokenPipeError:  # a plain line, written straight to the console's file
            self.console.on_broken_pipe()  # rich's answer for its own writes
        if getattr(self.console, "reader_gone", False):  # laboratory.console: it goes on
            self.quiet = True
            if self.progress is not None:
                self.progress.stop()  # to /dev/null now

    def _show(self, ev: dict) -> None:
        kind = ev.get("kind")
        # Text built here, not markup: a sheet's words print as they are written (a
        # bracket is no style tag) and rich parses no markup per line (issue 17: half
        # the cost of a tick)
        if kind == "sheet_start":
            title = self.console.highlighter(Text(f"  {ev['title']}"))  # as print highlights a str
            self._print(Text.assemble((f"Chart {ev['chart']}", "bold cyan"), title))
        elif kind == "step":
            t = ev["t_sim"]
            self._print(Text.assemble(
                "  ", ("\u2713", "green"), " ", (f"{t / 3600:6.3f} h", "dim"),
                f" {ev['chart']:>6} {ev['step']:<12} {ev['text']}"))
            if self.progress is not None and self.task is not None:
                self.progress.update(self.task, completed=min(t, EXPECTED_SIM_S),
                                     sim=f"{t / 3600:5.2f} h simulated")

    def _print(self, line: Text) -> None:
        """One line as console.print writes it (wrapped, a long word folded): written here
        when the console is plain and the line fits, which is what rich would write."""
        width = self.plain_width
        if width is not None and "\n" not in line.plain and cell_len(line.plain) <= width:
            self.console.file.write(line.plain + "\n")
        else:
            self.console.print(line, overflow="fold")  # the progress bar's console
