"""The commands' console (rich), whose reader may go away: `station day | head -1`.

rich answers a broken pipe by ending the process (SystemExit 1), which cut a run short at
its first line (the day at Chart I-1, marked aborted) or, for the gyrocompassing test and
the ESG calibration, while their tables printed beside the last plot (no plots, no end
note, a PASS verdict on an aborted run). The output is a view of the command, not its work:
here the console's descriptor goes to /dev/null instead, one line on stderr says so, and the
command goes on to its end. The reports are silent on this; the design is ours.
"""

from __future__ import annotations

import os
import sys

from rich.console import Console

NOTE = ("station: the reader of stdout went away (broken pipe); the command goes on to its "
        "end, its output discarded")


class StationConsole(Console):
    """rich's Console, whose broken pipe discards the output instead of ending the process."""

    reader_gone = False

    def on_broken_pipe(self) -> None:
        """The console's descriptor to /dev/null (nothing written later fails: the tables,
        the record's path, the flush at exit), and the note, once; the command goes on."""
        first, self.reader_gone = not self.reader_gone, True
        try:
            fd = self.file.fileno()
        except (AttributeError, OSError, ValueError):  # no descriptor: rich's own answer
            super().on_broken_pipe()
            return
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, fd)
        finally:
            os.close(null)
        if first:
            try:
                print(NOTE, file=sys.stderr, flush=True)
            except OSError:  # stderr went with it (2>&1 into the same pipe)
                pass
