"""The `station` console script (pyproject [project.scripts]): the garbage collector
deferred before anything is imported (laboratory.startup), then the command line
(laboratory.cli.run), which turns it on again at once unless the command is a run (a run
turns it on when it connects to its rack). Its own module, which imports nothing before
that, so that the command line's own imports come after it too (issue 17)."""

from __future__ import annotations


def run() -> None:
    """`station`: laboratory.cli.run with the collector deferred while it imports."""
    from laboratory import startup
    from station.numerics import pin_blas_threads_at_start

    startup.defer()
    pin_blas_threads_at_start()  # one BLAS thread, as the run pins it, from the start
    from laboratory.cli import run as cli_run

    cli_run()


if __name__ == "__main__":
    run()
