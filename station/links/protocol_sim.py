"""pyserial protocol handler for ``sim://NAME``: a serial port onto a simulated instrument.

Timeouts are simulated seconds; a blocking read advances the simulation inline.
"""

from __future__ import annotations

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from station.links import virtual


class Serial(SerialBase):
    """A pyserial port whose other end is a simulated instrument of the current rack."""

    is_open: bool  # set by SerialBase (untyped)
    def open(self) -> None:
        if self._port is None:
            raise SerialException("port must be configured before it can be used")
        if self.is_open:
            raise SerialException("port already open")
        try:
            self._ep, self._env = virtual.resolve_serial(self.portstr)
        except LookupError as e:
            raise SerialException(str(e)) from None
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def _reconfigure_port(self) -> None:
        pass

    def from_url(self, url: str) -> str:
        return url

    def _out(self) -> bytearray:
        if not self.is_open:
            raise PortNotOpenError()
        return self._ep.output

    @property
    def in_waiting(self) -> int:
        return len(self._out())

    def read(self, size: int = 1) -> bytes:
        out = self._out()
        virtual.run_until(self._env, lambda: len(out) >= size, self._timeout)
        n = min(size, len(out))
        data = bytes(out[:n])
        del out[:n]
        return data

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        out = self._out()

        def ready() -> bool:
            return expected in out or (size is not None and len(out) >= size)

        virtual.run_until(self._env, ready, self._timeout)
        i = out.find(expected)
        n = i + len(expected) if i >= 0 else len(out)
        if size is not None:
            n = min(n, size)
        data = bytes(out[:n])
        del out[:n]
        return data

    readline = read_until

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        b = bytes(data)
        self._ep.receive(b)
        return len(b)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        self._out().clear()

    def reset_output_buffer(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
