"""Driver of the patch panel (counter connections, Chart II-2)."""

from __future__ import annotations

from station.drivers.serial_base import SerialDriver


class PatchPanelDriver(SerialDriver):
    def connect(self, line: str, counter: int, inp: str) -> None:
        self.command(f"CONN {line} C{counter} {inp}")

    def disconnect(self, counter: int, inp: str) -> None:
        self.command(f"DISC C{counter} {inp}")

    def connection(self, counter: int, inp: str) -> str | None:
        r = self.query(f"CONN? C{counter} {inp}")
        return None if r == "NONE" else r

    def clear_all(self) -> None:
        self.command("CLR")

    def lines(self) -> list[str]:
        return self.query("LINES?").split(",")
