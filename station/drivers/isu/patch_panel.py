"""Driver of the patch panel (counter connections, Chart II-2)."""

from __future__ import annotations

from station.drivers.replies import Form, ListForm, word
from station.drivers.serial_base import SerialDriver

# the pulse lines of the laboratory (docs/protocols.md, "Patch panel")
LINES = (*(f"G{k}{s}" for k in (1, 2, 3) for s in ("", "+", "-")),
         *(f"A{k}S{s}" for k in (1, 2, 3) for s in (1, 2)), "TROT", "OSC1", "OSC2")
CONNECTION = Form([word("line or NONE", *LINES, "NONE")])
LINE_LIST = ListForm(word("line", *LINES), sep=",", lo=1, hi=len(LINES))


class PatchPanelDriver(SerialDriver):
    model = ("ISU-LAB", "PATCH-PANEL")

    def connect(self, line: str, counter: int, inp: str) -> None:
        self.command(f"CONN {line} C{counter} {inp}")

    def disconnect(self, counter: int, inp: str) -> None:
        self.command(f"DISC C{counter} {inp}")

    def connection(self, counter: int, inp: str) -> str | None:
        r = self.ask(f"CONN? C{counter} {inp}", CONNECTION)[0]
        return None if r == "NONE" else r

    def clear_all(self) -> None:
        self.command("CLR")

    def lines(self) -> list[str]:
        return self.ask("LINES?", LINE_LIST)
