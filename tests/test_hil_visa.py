"""A standard VISA client reaches the served serial instruments: pyvisa with pyvisa-py.

The rack is served by another process (tests/hil_helpers.py); pyvisa opens each pty as
``ASRL<path>::INSTR`` (the pty device, and the stable symlink) and talks to the
instruments as it would to the hardware: identification, a table move read back from the
resolver, the oscillator's countdown, and an unknown command answered with the
instrument's own error reply.
"""

from __future__ import annotations

import os

import pytest
import pyvisa
from hil_helpers import serving

SPEED = 20.0


@pytest.fixture(scope="module")
def visa(tmp_path_factory):
    base = tmp_path_factory.mktemp("visa")
    args = ["--seed", "5", "--speed", str(SPEED), "--only", "table,oscillator,counter2"]
    with serving(base, args) as (links, entries, _proc):
        rm = pyvisa.ResourceManager("@py")
        try:
            yield rm, links
        finally:
            rm.close()


def _open(rm: pyvisa.ResourceManager, path: str):
    inst = rm.open_resource(f"ASRL{path}::INSTR", read_termination="\n",
                            write_termination="\n", timeout=5000)
    return inst


@pytest.mark.parametrize("name, ident", [("table", "TT-4AX"), ("oscillator", "MO-5M"),
                                         ("counter2", "FC-1,C2")])
def test_visa_identifies_each_instrument_on_its_pty(visa, name, ident):
    rm, links = visa
    dev = os.path.realpath(links / name)
    assert dev.startswith("/dev/pts/")
    inst = _open(rm, dev)
    try:
        reply = inst.query("*IDN?")
    finally:
        inst.close()
    assert reply.startswith("ISU-LAB,") and ident in reply


def test_visa_moves_the_table_and_reads_the_resolver(visa):
    rm, links = visa
    inst = _open(rm, os.path.realpath(links / "table"))
    try:
        assert inst.query("POS 3 12.5") == "OK"
        status = [inst.query("STAT?") for _ in range(3)]
        while status[-1].split(",")[2] != "HOLD" and len(status) < 20000:
            status.append(inst.query("STAT?"))  # the axis slews in the rack's time
        angle = float(inst.query("POS? 3"))
    finally:
        inst.close()
    assert "MOVING" in status[0] and status[-1] == "HOLD,HOLD,HOLD,HOLD"
    assert abs(angle - 12.5) < 0.001  # resolver reading within a few arcsec of the command


def test_visa_gets_the_instruments_error_reply(visa):
    rm, links = visa
    inst = _open(rm, str(links / "oscillator"))  # the stable symlink works too
    try:
        reply = inst.query("FROB 1")
        assert reply.startswith("ERR 10") and "FROB" in reply
        assert inst.query("DIV?").split()  # and it goes on answering
    finally:
        inst.close()
