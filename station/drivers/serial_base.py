"""Line-protocol exchange over any pyserial URL (sim://, a pty, /dev/ttyUSB0, socket://...).

One command, one reply line. Timeouts, garbled replies and error replies become
DriverError subclasses naming the instrument, the link and the current procedure step.
"""

from __future__ import annotations

from collections.abc import Callable

import serial

import station.links  # noqa: F401  (registers the sim:// handler)
from station.errors import DriverError, InstrumentRefused, LinkTimeout


class SerialDriver:
    def __init__(self, name: str, url: str, timeout: float = 5.0) -> None:
        self.name = name
        self.url = url
        self.timeout = timeout
        self.link_seconds: Callable[[float], float] = float  # station -> link timeout
        try:
            self.port = serial.serial_for_url(url, timeout=timeout, baudrate=115200)
        except (serial.SerialException, OSError, ValueError) as e:
            raise DriverError(name, url, f"cannot open link: {e}") from None

    def bind_clock(self, clock) -> None:
        """Give the link its timeouts in wall seconds when the station runs on a real-time
        clock (a served rack may run faster than the wall); virtual links keep them."""
        self.link_seconds = clock.link_seconds
        self.port.timeout = self.link_seconds(self.timeout)

    def close(self) -> None:
        self.port.close()

    def query(self, cmd: str, timeout: float | None = None) -> str:
        """Send one command line; return its reply (error replies raise InstrumentRefused)."""
        port = self.port
        try:
            if timeout is not None:
                port.timeout = self.link_seconds(timeout)
            port.write((cmd + "\n").encode("ascii"))
            raw = port.read_until(b"\n")
        except (serial.SerialException, OSError) as e:
            raise DriverError(self.name, self.url, f"link failed during '{cmd}': {e}") from None
        finally:
            if timeout is not None:
                port.timeout = self.link_seconds(self.timeout)
        if not raw.endswith(b"\n"):
            waited = self.timeout if timeout is None else timeout
            got = f" (partial reply {raw[:40]!r})" if raw else ""
            raise LinkTimeout(self.name, self.url, f"no reply to '{cmd}' within {waited:g} s{got}")
        try:
            text = raw.decode("ascii").strip()
        except UnicodeDecodeError:
            raise DriverError(
                self.name, self.url, f"garbled reply to '{cmd}': {raw[:40]!r}"
            ) from None
        if text.startswith("ERR"):
            parts = text.split(" ", 2)
            try:
                code = int(parts[1])
            except (IndexError, ValueError):
                raise DriverError(self.name, self.url, f"malformed error reply {text!r}") from None
            raise InstrumentRefused(self.name, self.url, code, parts[2] if len(parts) > 2 else "")
        return text

    def command(self, cmd: str, timeout: float | None = None) -> None:
        reply = self.query(cmd, timeout)
        if reply != "OK":
            raise DriverError(self.name, self.url, f"unexpected reply {reply!r} to '{cmd}'")

    def numbers(self, cmd: str, n: int) -> list[float]:
        reply = self.query(cmd)
        try:
            vals = [float(x) for x in reply.split()]
        except ValueError:
            vals = []
        if len(vals) != n:
            raise DriverError(
                self.name, self.url, f"expected {n} numbers from '{cmd}', got {reply!r}"
            )
        return vals

    def identify(self) -> str:
        return self.query("*IDN?")

    def clear(self) -> None:
        """Device clear: drop pending replies and the error queue."""
        self.port.reset_input_buffer()
        self.command("*CLS")
