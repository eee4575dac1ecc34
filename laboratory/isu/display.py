"""The live display of `station day` and `station align`: check-sheet ticks as they happen
and a progress bar in simulated time."""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn

EXPECTED_SIM_S = 9.0 * 3600.0  # for the progress bar only


class DayDisplay:
    """Check-sheet ticks as they happen, and a progress bar in simulated time."""

    def __init__(self, console: Console, quiet: bool = False) -> None:
        self.console = console
        self.quiet = quiet
        self.progress = Progress(
            TextColumn("[bold]{task.description}"), BarColumn(),
            TextColumn("{task.fields[sim]}"), console=console, transient=True,
        )
        self.task = self.progress.add_task("calibration day", total=EXPECTED_SIM_S, sim="")

    def __enter__(self) -> DayDisplay:
        if not self.quiet:
            self.progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if not self.quiet:
            self.progress.stop()

    def __call__(self, ev: dict) -> None:
        if self.quiet:
            return
        kind = ev.get("kind")
        if kind == "sheet_start":
            self.progress.console.print(f"[bold cyan]Chart {ev['chart']}[/]  {ev['title']}")
        elif kind == "step":
            t = ev["t_sim"]
            self.progress.console.print(
                f"  [green]\u2713[/] [dim]{t / 3600:6.3f} h[/] {ev['chart']:>6} "
                f"{ev['step']:<12} {ev['text']}", highlight=False, overflow="fold",
            )
            self.progress.update(self.task, completed=min(t, EXPECTED_SIM_S),
                                 sim=f"{t / 3600:5.2f} h simulated")
