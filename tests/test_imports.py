"""Commands start at once: what a command line imports before it runs anything (issue 17).

Exact assertions on the modules a fresh interpreter holds after an import, never timings:
the command line itself loads no numerical, plotting, database or template package; the
path of `station day` up to the start of the run loads no plotting, templates, database,
and of scipy only what the simulation itself calls (not scipy.signal, .integrate, .stats).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("matplotlib", "scipy", "sqlalchemy", "jinja2", "pandas")


def loaded(module: str, prefixes: tuple[str, ...]) -> list[str]:
    """The modules named by ``prefixes`` (a package and its submodules) that a fresh
    interpreter holds after ``import module``."""
    code = (f"import json, sys, {module}; print(json.dumps(sorted(m for m in sys.modules "
            f"if any(m == p or m.startswith(p + '.') for p in {list(prefixes)!r}))))")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                         text=True, check=True).stdout
    return list(json.loads(out))


def test_the_command_line_loads_no_heavy_package() -> None:
    """`import laboratory.cli` (every command registered, `station --help`) loads none of
    matplotlib, scipy, sqlalchemy, jinja2, pandas."""
    assert loaded("laboratory.cli", HEAVY) == []


def test_the_command_line_loads_neither_the_config_nor_the_simulation() -> None:
    """Nor pydantic, numpy, simpy or the CAN database: a command imports its own
    laboratory's modules when it runs."""
    assert loaded("laboratory.cli", ("numpy", "pydantic", "simpy", "cantools", "can")) == []


def test_the_day_before_its_run_loads_no_plots_reports_or_history() -> None:
    """`station day`'s modules, imported before the run starts: matplotlib (the plots),
    jinja2 (the report), sqlalchemy (the history) and the parts of scipy the simulation does
    not call are imported only when (and if) they are used."""
    mods = loaded("laboratory.isu.day", HEAVY)
    assert [m for m in mods if m.split(".")[0] != "scipy"] == []
    unused = ("scipy.signal", "scipy.integrate", "scipy.stats", "scipy.interpolate")
    assert [m for m in mods if m.startswith(unused)] == []


def test_a_virtual_run_loads_no_served_rack_module() -> None:
    """The day's and the alignment's modules hold none of station.hil (the served rack's
    profile, session and server): a run in virtual time attaches to no served rack, and
    those modules build pydantic models at import (issue 17)."""
    assert loaded("laboratory.isu.day", ("station.hil",)) == []
    assert loaded("laboratory.isu.align", ("station.hil",)) == []


def test_help_loads_no_rich() -> None:
    """`station --help` (every command registered, the help printed) loads no part of rich:
    the help is click's plain text, the console is made by the first command that prints."""
    code = ("import contextlib, io, json, sys; sys.argv = ['station', '--help']\n"
            "import laboratory.cli as c\n"
            "with contextlib.redirect_stdout(io.StringIO()) as out, "
            "contextlib.suppress(SystemExit):\n    c.main()\n"
            "assert 'Commands:' in out.getvalue() and 'day' in out.getvalue()\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('rich', 'markdown_it'))))")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                         text=True, check=True).stdout
    assert json.loads(out) == []


def test_the_laboratories_without_can_load_no_asyncio() -> None:
    """The gyrocompassing test's and the ESG calibration's modules load no asyncio: they use
    no CAN (python-can imports it for the ISU), and pydantic_core's deprecated functions no
    longer pull it in (typing_extensions >= 4.16: 21-27 ms of each process)."""
    for module in ("laboratory.cigtf.gyrocompassing", "laboratory.esg.calibration"):
        assert loaded(module, ("asyncio", "can")) == [], module
        assert loaded(module, ("pydantic_core",)) != [], module  # the path under test


def test_a_quiet_day_loads_no_rich(tmp_path: Path) -> None:
    """`station day --quiet` shows nothing, so it makes no console: no part of rich is
    imported, from the command line to the record's end (13 ms of a day); the same day
    without --quiet shows its ticks and tables through rich.console."""
    code = ("import json, sys; sys.argv = ['station', *sys.argv[1:]]\n"
            "import contextlib, laboratory.cli as c\n"
            "with contextlib.suppress(SystemExit):\n    c.main()\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] == 'rich')),"
            " file=sys.stderr)")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    seen = {}
    for quiet in (True, False):
        out = tmp_path / f"quiet{quiet}"
        args = ["day", "--seed", "5", "--only", "II-11", "--positions", "7", "--out", str(out),
                *(["--quiet"] if quiet else [])]
        r = subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, env=env,
                           capture_output=True, text=True, check=True)
        assert (out / "results.json").is_file()
        seen[quiet] = json.loads(r.stderr.strip().splitlines()[-1])
    assert seen[True] == []
    assert "rich.console" in seen[False]
