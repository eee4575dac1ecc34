"""Layer boundaries, checked on the source (AST):

* procedures (and the drivers) never import ``sim`` or ``instruments``: they reach the lab
  only through drivers bound to links, which is what makes the HIL and hardware runs real;
* procedures and drivers never read or wait on the wall clock (``time.sleep``,
  ``time.time`` and friends): they use the station clock and the links' own timeouts.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
IMPORT_CHECKED = ("procedures", "station/drivers")
CLOCK_CHECKED = ("procedures", "station/drivers")
FORBIDDEN_PACKAGES = {"sim", "instruments"}
WALL_CLOCK = {
    "sleep",
    "time",
    "time_ns",
    "monotonic",
    "monotonic_ns",
    "perf_counter",
    "perf_counter_ns",
}
DYNAMIC_IMPORTS = {"import_module", "__import__"}


def python_files(folder: str) -> list[Path]:
    return sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)


def package_of(path: Path) -> list[str]:
    """Dotted package (as parts) that relative imports in ``path`` start from."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return parts[:-1]  # a package's __init__ and a plain module both start from their folder


def absolute(module: str | None, level: int, package: list[str]) -> str:
    if level == 0:
        return module or ""
    base = package[: len(package) - (level - 1)] if level - 1 <= len(package) else []
    return ".".join([*base, *([module] if module else [])])


def imported_modules(tree: ast.AST, package: list[str]) -> list[tuple[int, str]]:
    """(line, dotted name) of every module an import statement or a literal
    importlib.import_module / __import__ call may load."""
    out: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = absolute(node.module, node.level, package)
            # `from ... import sim` climbing above the top level names the package itself
            out += [(node.lineno, base)] if base else [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.Call):
            f = node.func
            name = (
                f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
            )
            if name not in DYNAMIC_IMPORTS:
                continue
            args = [*node.args[:1], *(k.value for k in node.keywords if k.arg == "name")]
            for a in args:
                if isinstance(a, ast.Constant) and isinstance(a.value, str):
                    rel = len(a.value) - len(a.value.lstrip("."))
                    out.append((node.lineno, absolute(a.value.lstrip(".") or None, rel, package)))
    return out


def forbidden_imports(source: str, package: list[str]) -> list[str]:
    tree = ast.parse(source)
    return [
        f"line {line}: imports {name}"
        for line, name in imported_modules(tree, package)
        if name.split(".")[0] in FORBIDDEN_PACKAGES
    ]


def wall_clock_uses(source: str) -> list[str]:
    tree = ast.parse(source)
    aliases = {  # names bound to the time module
        a.asname or a.name
        for n in ast.walk(tree)
        if isinstance(n, ast.Import)
        for a in n.names
        if a.name == "time"
    }
    hits = []
    for n in ast.walk(tree):
        if isinstance(n, ast.ImportFrom) and n.level == 0 and n.module == "time":
            hits += [
                f"line {n.lineno}: from time import {a.name}"
                for a in n.names
                if a.name in WALL_CLOCK or a.name == "*"
            ]
        elif (
            isinstance(n, ast.Attribute)
            and isinstance(n.value, ast.Name)
            and n.value.id in aliases
            and n.attr in WALL_CLOCK
        ):
            hits.append(f"line {n.lineno}: {n.value.id}.{n.attr}")
    return sorted(set(hits), key=lambda h: int(h.split()[1].rstrip(":")))


# ----------------------------------------------------------------------------- the code


@pytest.mark.parametrize("folder", sorted({*IMPORT_CHECKED, *CLOCK_CHECKED}))
def test_checked_folders_are_not_empty(folder):
    files = python_files(folder)
    assert files, f"no Python files under {folder}/: the boundary tests would pass vacuously"


@pytest.mark.parametrize("folder", IMPORT_CHECKED)
def test_no_sim_or_instruments_imports(folder):
    bad = {
        str(p.relative_to(ROOT)): hits
        for p in python_files(folder)
        if (hits := forbidden_imports(p.read_text(), package_of(p)))
    }
    assert not bad, f"{folder}/ must reach the lab through drivers only: {bad}"


@pytest.mark.parametrize("folder", CLOCK_CHECKED)
def test_no_wall_clock(folder):
    bad = {
        str(p.relative_to(ROOT)): hits
        for p in python_files(folder)
        if (hits := wall_clock_uses(p.read_text()))
    }
    assert not bad, f"{folder}/ must use the station clock, not the wall clock: {bad}"


# ----------------------------------------------------------------------------- the checkers

PKG = ["procedures", "survey"]  # as if the snippet were procedures/survey/<module>.py


@pytest.mark.parametrize(
    "source",
    [
        "import sim",
        "import sim.isu.world as w",
        "import numpy, instruments.isu.counter",
        "from sim import units",
        "from sim.isu.world import World",
        "from instruments import base",
        "from instruments.isu.counter import FrequencyCounter as C",
        "def f():\n    import sim.isu.pulses\n",
        "from ... import sim",  # relative, climbing out of procedures/
        "import importlib\nm = importlib.import_module('sim.isu.world')",
        "from importlib import import_module\nimport_module('instruments')",
        "import importlib as il\nil.import_module(name='instruments.isu.ieu')",
        "m = __import__('sim')",
    ],
)
def test_import_checker_flags(source):
    assert forbidden_imports(source, PKG)


@pytest.mark.parametrize(
    "source",
    [
        "import simpy",
        "import simulation_tools",
        "from station.drivers.isu import TableDriver",
        "from station.errors import DriverError",
        "from . import sheets",
        "from .instruments_table import rows",  # procedures.survey.instruments_table
        "import importlib\nm = importlib.import_module(name)",
        "import importlib\nm = importlib.import_module('.sim', 'procedures')",
        "x = 'import sim'",
    ],
)
def test_import_checker_passes(source):
    assert forbidden_imports(source, PKG) == []


@pytest.mark.parametrize(
    "source",
    [
        "import time\ntime.sleep(1)",
        "import time\nt0 = time.time()",
        "import time as t\nt.monotonic()",
        "import os, time\nwait = time.sleep",
        "from time import sleep",
        "from time import time as now",
        "from time import perf_counter",
        "from time import *",
    ],
)
def test_wall_clock_checker_flags(source):
    assert wall_clock_uses(source)


@pytest.mark.parametrize(
    "source",
    [
        "import time\nstamp = time.strftime('%Y')",
        "clock.sleep(1.0)",
        "t = self.clock.now()",
        "from station.clock import Clock",
        "import datetime",
        "def time():\n    return 0\ntime()",
    ],
)
def test_wall_clock_checker_passes(source):
    assert wall_clock_uses(source) == []
