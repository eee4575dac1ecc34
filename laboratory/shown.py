"""A command's display of its results, made while the run's plot child draws the last plot
(issue 17): the display and the report's template then wait for the child together, not one
after the other. A display error must not cut the record short, so it is kept and raised
only where the display used to be made, once the record is complete (a closed stdout is no
error: laboratory/console.py)."""

from __future__ import annotations

from collections.abc import Callable

from laboratory.report import prepare_report


class Shown:
    """``show(res)`` made early (``meanwhile``) or else at ``done``; its error raised by
    ``done``, once the record is complete. ``show`` None: nothing is displayed. ``prepare``
    False: the report is written by the plot child, which has its template ready."""

    def __init__(self, show: Callable[[dict], None] | None, prepare: bool = True) -> None:
        self.show = show
        self.prepare = prepare  # False: the plot child compiles the template (report_after)
        self.made = False
        self.error: Exception | None = None

    def meanwhile(self, res: dict) -> None:
        """The report's template, then the display of ``res`` (an error kept for ``done``)."""
        if self.prepare:
            prepare_report()
        if self.show is not None and not self.made:
            self.made = True
            try:
                self.show(res)
            except Exception as e:  # noqa: BLE001 - raised by done, after the record
                self.error = e

    def done(self, res: dict) -> None:
        """The display of ``res`` if the run made none (a run that drew no plot), else
        its error, if it had one."""
        if self.show is not None and not self.made:
            self.made = True
            self.show(res)
        if self.error is not None:
            error, self.error = self.error, None
            raise error
