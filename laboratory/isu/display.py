"""The live display of `station day` and `station align`: check-sheet ticks as they happen
and a progress bar in simulated time. When the console's reader goes away
(laboratory.console) the display goes quiet and the run goes on."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # rich is imported when something is shown: a quiet run imports none of it
    from rich.console import Console
    from rich.progress import Progress, TaskID
    from rich.text import Text

EXPECTED_SIM_S = 9.0 * 3600.0  # for the progress bar only


def shown_console(console: Console | None, quiet: bool) -> Console | None:
    """The console a run shows itself on: none for a quiet run (rich.console is then never
    imported: 13 ms of a quiet day, issue 17), else the one given or a new rich Console."""
    if quiet:
        return None
    if console is None:
        from rich.console import Console

        return Console()
    return console


class DayDisplay:
    """Check-sheet ticks as they happen, and a progress bar in simulated time; nothing
    without a console."""

    def __init__(self, console: Console | None) -> None:
        # a quiet console shows nothing, written or not (a quiet run has none: shown_console)
        self.console = None if console is None or console.quiet else console
        self.progress: Progress | None = None
        self.task: TaskID | None = None
        self.plain_width: int | None = None
        if self.console is None:
            return
        from rich.progress import BarColumn, Progress, TextColumn  # a bar shown: 10 ms

        self.progress = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(),
            TextColumn("{task.fields[sim]}"), console=self.console, transient=True,
        )
        self.task = self.progress.add_task("calibration day", total=EXPECTED_SIM_S, sim="")
        # piped or redirected: no colours and no bar, so a line that fits is the text itself
        self.plain_width = None if self.console.is_terminal else self.console.width

    @property
    def quiet(self) -> bool:
        """Nothing is shown (any more: a reader gone makes the display quiet)."""
        return self.console is None

    def __enter__(self) -> DayDisplay:
        if self.progress is not None:
            self.progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.console is not None and self.progress is not None:
            try:
                self.progress.stop()
            except BrokenPipeError:
                self.console.on_broken_pipe()

    def __call__(self, ev: dict) -> None:
        console = self.console
        if console is None:
            return
        try:
            self._show(console, ev)
        except BrokenPipeError:  # a plain line, written straight to the console's file
            console.on_broken_pipe()  # rich's answer for its own writes
        if getattr(console, "reader_gone", False):  # laboratory.console: it goes on
            self.console = None
            if self.progress is not None:
                self.progress.stop()  # to /dev/null now

    def _show(self, console: Console, ev: dict) -> None:
        from rich.text import Text

        kind = ev.get("kind")
        # Text built here, not markup: a sheet's words print as they are written (a
        # bracket is no style tag) and rich parses no markup per line (issue 17: half
        # the cost of a tick)
        if kind == "sheet_start":
            title = console.highlighter(Text(f"  {ev['title']}"))  # as print highlights a str
            self._print(console, Text.assemble((f"Chart {ev['chart']}", "bold cyan"), title))
        elif kind == "step":
            t = ev["t_sim"]
            self._print(console, Text.assemble(
                "  ", ("\u2713", "green"), " ", (f"{t / 3600:6.3f} h", "dim"),
                f" {ev['chart']:>6} {ev['step']:<12} {ev['text']}"))
            if self.progress is not None and self.task is not None:
                self.progress.update(self.task, completed=min(t, EXPECTED_SIM_S),
                                     sim=f"{t / 3600:5.2f} h simulated")

    def _print(self, console: Console, line: Text) -> None:
        """One line as console.print writes it (wrapped, a long word folded): written here
        when the console is plain and the line fits, which is what rich would write."""
        from rich.cells import cell_len

        width = self.plain_width
        if width is not None and "\n" not in line.plain and cell_len(line.plain) <= width:
            console.file.write(line.plain + "\n")
        else:
            console.print(line, overflow="fold")  # the progress bar's console
