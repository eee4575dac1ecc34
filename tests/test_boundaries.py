"""Layer boundaries, checked on the source (AST), from every import statement there is.

An import is read wherever it stands: at module level, inside a function, under
``if TYPE_CHECKING:``, relative, or as ``importlib.import_module("...")`` / ``__import__``
with a literal name. From them the graph of the project's modules is built, and:

* floors: ``sim`` < ``instruments`` < ``station`` < ``procedures`` < ``laboratory``; no
  module imports a higher floor (a typing-only import counts: it is a dependency too);
* procedures reach the laboratory only through drivers bound to links: nothing a procedure
  module imports, directly or through what those import, is in ``instruments`` or in
  ``sim`` except the pure arithmetic of ``sim.timebase`` and ``sim.units``;
  the drivers import neither ``sim`` nor ``instruments`` themselves;
* no import cycle between modules (a package's ``__init__`` importing its own children is
  how a package is made, not a cycle);
* procedures and drivers never read or wait on the wall clock (``time.sleep``,
  ``time.time`` and friends): they use the station clock and the links' own timeouts.

Each failure names the chain of imports that breaks the rule, with the line of each.
"""

from __future__ import annotations

import ast
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FLOORS = ("sim", "instruments", "station", "procedures", "laboratory")  # low to high
RESOURCES = ("config",)  # data shipped with the code: any floor reads it, it imports no floor
NOT_PACKAGES = {"tests", "bench", "docs", "build"}
PURE_SIM = ("sim.timebase", "sim.units")  # what procedures may use of sim
PROCEDURES = "procedures"
SIMULATOR = ("sim", "instruments")
LAB_BOUNDARY = ("station.drivers",)  # import neither sim nor instruments themselves
CLOCK_CHECKED = ("procedures", "station/drivers")
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


# ----------------------------------------------------------------------------- reading imports


@dataclass(frozen=True)
class Imported:
    """One import: the module it names and, for ``from module import a, b``, the names
    (each a submodule or an attribute of the module: the graph tells which)."""

    line: int
    module: str
    names: tuple[str, ...] = ()
    typing_only: bool = False


def _absolute(module: str | None, level: int, package: list[str]) -> str:
    """The dotted name a (possibly relative) import names, from ``package``."""
    if level == 0:
        return module or ""
    base = package[: len(package) - (level - 1)] if level - 1 < len(package) else []
    return ".".join([*base, *([module] if module else [])])


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _typing_only_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes inside the body of an ``if TYPE_CHECKING:``."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            out |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return out


def _literal(node: ast.expr | None) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def imported_names(source: str, package: list[str]) -> list[Imported]:
    """Every name an import statement or a literal importlib.import_module / __import__ call
    in ``source`` may load; relative names are made absolute from ``package`` (the dotted
    package, as parts, the file's relative imports start from)."""
    tree = ast.parse(source)
    typing_only = _typing_only_nodes(tree)
    out: list[Imported] = []
    for node in ast.walk(tree):
        t = id(node) in typing_only
        if isinstance(node, ast.Import):
            out += [Imported(node.lineno, a.name, (), t) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = tuple(a.name for a in node.names if a.name != "*")
            out.append(Imported(node.lineno, _absolute(node.module, node.level, package), names, t))
        elif isinstance(node, ast.Call):
            f = node.func
            name = (
                f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
            )
            if name not in DYNAMIC_IMPORTS:
                continue
            kw = {k.arg: k.value for k in node.keywords}
            target = _literal(node.args[0] if node.args else kw.get("name"))
            if target is None:
                continue  # a computed name: nothing to read
            rel = len(target) - len(target.lstrip("."))
            anchor = package
            if rel and name == "import_module":
                given = _literal(node.args[1] if len(node.args) > 1 else kw.get("package"))
                anchor = given.split(".") if given else package
            module = _absolute(target.lstrip(".") or None, rel, anchor)
            out.append(Imported(node.lineno, module, (), t))
    return out


# ----------------------------------------------------------------------------- the graph


@dataclass(frozen=True)
class Edge:
    """An import of one module by another: the first line, whether typing only (every
    import of it is), and whether only implied (a package loaded as the parent of the
    module named)."""

    line: int
    typing_only: bool
    implied: bool = False

    def note(self) -> str:
        return f"line {self.line}{', typing only' if self.typing_only else ''}"

    def merged(self, other: Edge) -> Edge:
        return Edge(min(self.line, other.line), self.typing_only and other.typing_only,
                    self.implied and other.implied)


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def is_package(module: str, modules: dict[str, Path]) -> bool:
    return modules[module].name == "__init__.py"


def python_modules(root: Path, tops: Iterable[str]) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of the given top-level packages."""
    out = {}
    for top in tops:
        for p in sorted((root / top).rglob("*.py")):
            if "__pycache__" not in p.parts:
                out[module_name(p, root)] = p
    return out


def ancestors(module: str) -> list[str]:
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The project module a dotted name loads: itself, or its longest module prefix (the
    rest names attributes); None if it is not the project's."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def targets(imp: Imported, modules: dict[str, Path]) -> list[str]:
    """The project modules an import names: ``from X import a`` names X.a if that is a
    module, else X (a is one of its attributes); ``from . import a`` climbing out of the
    project names the top-level a."""
    out = []
    for n in imp.names:
        sub = resolve(f"{imp.module}.{n}" if imp.module else n, modules)
        if sub is not None and (not imp.module or sub != resolve(imp.module, modules)):
            out.append(sub)
        elif imp.module:
            out.append(imp.module)
    if not imp.names:
        out.append(imp.module)
    return [r for n in dict.fromkeys(out) if (r := resolve(n, modules)) is not None]


def import_graph(root: Path, tops: Iterable[str]
                 ) -> tuple[dict[str, Path], dict[str, dict[str, Edge]]]:
    """The modules of ``tops`` under ``root`` and, for each, the project modules it imports.
    Importing ``a.b.c`` also loads the packages ``a`` and ``a.b``: those count too (implied),
    except the importer's own ancestors (Python loads them before the importer)."""
    modules = python_modules(root, tops)
    graph: dict[str, dict[str, Edge]] = {}
    for m, path in modules.items():
        package = m.split(".") if path.name == "__init__.py" else m.split(".")[:-1]
        own = set(ancestors(m))
        edges: dict[str, Edge] = {}
        for imp in imported_names(path.read_text(), package):
            for target in targets(imp, modules):
                found = [(a, True) for a in ancestors(target) if a not in own]
                for t, implied in [*found, (target, False)]:
                    if t != m:
                        e = Edge(imp.line, imp.typing_only, implied)
                        edges[t] = edges[t].merged(e) if t in edges else e
        graph[m] = edges
    return modules, graph


def chain_text(path: list[str], graph: dict[str, dict[str, Edge]]) -> str:
    """``a (line 3) -> b (line 9, typing only) -> c``: each import with the line it stands on."""
    hops = [f"{a} ({graph[a][b].note()})" for a, b in zip(path, path[1:], strict=False)]
    return " -> ".join([*hops, path[-1]])


def shortest_path(graph: dict[str, dict[str, Edge]], start: str, goal: set[str],
                  allowed: set[str] | None = None) -> list[str] | None:
    """Fewest imports from ``start`` to a module of ``goal`` (through ``allowed`` only)."""
    prev: dict[str, str | None] = {start: None}
    queue = deque([start])
    while queue:
        v = queue.popleft()
        for w in sorted(graph.get(v, {}), key=lambda n: (-n.count("."), n)):  # deepest first
            if w in prev or (allowed is not None and w not in allowed):
                continue
            prev[w] = v
            if w in goal:
                path = [w]
                while (p := prev[path[-1]]) is not None:
                    path.append(p)
                return path[::-1]
            queue.append(w)
    return None


# ----------------------------------------------------------------------------- the rules


def floor_of(module: str) -> int | None:
    top = module.split(".")[0]
    return FLOORS.index(top) if top in FLOORS else None


def upward_imports(graph: dict[str, dict[str, Edge]]) -> list[str]:
    """Imports of a higher floor (resources import no floor at all)."""
    out = []
    for m, edges in sorted(graph.items()):
        fm = floor_of(m)
        for t, e in sorted(edges.items()):
            ft = floor_of(t)
            if not e.implied and ft is not None and (fm is None or ft > fm):
                below = FLOORS[fm] if fm is not None else f"resource {m.split('.')[0]}"
                out.append(f"{m} ({e.note()}) imports {t}: {FLOORS[ft]} is above {below}")
    return out


def simulator_module(module: str) -> bool:
    """In the simulator, as procedures see it: instruments, and sim but its pure arithmetic
    (and the packages holding that)."""
    pure = {*PURE_SIM, *(a for p in PURE_SIM for a in ancestors(p))}
    return module.split(".")[0] in SIMULATOR and module not in pure


def procedures_reaching_the_simulator(graph: dict[str, dict[str, Edge]]) -> list[str]:
    """For each procedure module that reaches the simulator through what it imports, the
    shortest such chain."""
    bad = {m for m in graph if simulator_module(m)}
    out = []
    for m in sorted(graph):
        if m.split(".")[0] == PROCEDURES and (path := shortest_path(graph, m, bad)):
            out.append(chain_text(path, graph))
    return out


def direct_lab_imports(graph: dict[str, dict[str, Edge]], packages: Iterable[str]) -> list[str]:
    out = []
    for m, edges in sorted(graph.items()):
        if any(m == p or m.startswith(p + ".") for p in packages):
            out += [f"{m} ({e.note()}) imports {t}" for t, e in sorted(edges.items())
                    if not e.implied and t.split(".")[0] in SIMULATOR]
    return out


def cycle_edges(graph: dict[str, dict[str, Edge]], modules: dict[str, Path]) -> dict[str, set[str]]:
    """The graph without a package ``__init__``'s imports of its own children."""
    return {
        m: {t for t in edges if not (is_package(m, modules) and t.startswith(m + "."))}
        for m, edges in graph.items()
    }


def import_cycles(graph: dict[str, dict[str, Edge]], modules: dict[str, Path]) -> list[str]:
    """One chain per strongly connected group of modules: the shortest cycle through its
    first member (by name), and the other members of the group."""
    succ = cycle_edges(graph, modules)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[list[str]] = []

    def strong(root: str) -> None:  # Tarjan's algorithm, iterative (deep chains)
        work = [(root, iter(sorted(succ[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(succ[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    group = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        group.append(w)
                        if w == v:
                            break
                    if len(group) > 1:
                        groups.append(sorted(group))

    for v in sorted(succ):
        if v not in index:
            strong(v)
    out = []
    sub = {m: {t: graph[m][t] for t in succ[m]} for m in succ}
    for group in sorted(groups):
        first, members = group[0], set(group)
        back = {m for m in group if first in sub[m]}
        path = shortest_path(sub, first, back, allowed=members) if first not in back else [first]
        assert path is not None, f"no cycle found in the strongly connected group {group}"
        others = sorted(members - set(path))
        also = f" (with {', '.join(others)})" if others else ""
        out.append(chain_text([*path, first], graph) + also)
    return out


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

MODULES, GRAPH = import_graph(ROOT, (*FLOORS, *RESOURCES))


def listing(problems: list[str]) -> str:
    return "\n  " + "\n  ".join(problems)


def test_every_package_is_a_floor_or_a_resource():
    tops = sorted(p.parent.name for p in ROOT.glob("*/__init__.py"))
    stray = [t for t in tops if t not in (*FLOORS, *RESOURCES, *NOT_PACKAGES)]
    assert not stray, f"top-level packages outside the floors (unchecked): {stray}"
    for top in FLOORS:
        assert any(m.split(".")[0] == top for m in MODULES), f"no modules in {top}/"


def line_of(rel: str, text: str) -> int:
    """The line of ``rel`` (a file of the project) holding ``text``."""
    lines = (ROOT / rel).read_text().splitlines()
    return next(i for i, line in enumerate(lines, 1) if text in line)


def test_the_graph_holds_every_module_and_import():
    """The graph the rules read sees what a reader sees: module level, function level and
    typing-only imports, each at its line; packages loaded as parents are implied."""
    assert len(MODULES) > 150
    clock = line_of("station/clock.py", "from sim.timebase import")
    assert GRAPH["station.clock"]["sim.timebase"] == Edge(clock, typing_only=False)
    assert GRAPH["station.clock"]["sim"] == Edge(clock, typing_only=False, implied=True)
    typed = line_of("instruments/base.py", "    from instruments.output_faults import")
    assert GRAPH["instruments.base"]["instruments.output_faults"] == Edge(typed, typing_only=True)
    local = line_of("sim/isu/unit.py", "        from sim.rng import")  # inside a method
    assert GRAPH["sim.isu.unit"]["sim.rng"] == Edge(local, typing_only=False)


def test_no_module_imports_a_higher_floor():
    bad = upward_imports(GRAPH)
    assert not bad, f"floors are {' < '.join(FLOORS)}; upward imports:{listing(bad)}"


def test_procedures_do_not_reach_the_simulator():
    bad = procedures_reaching_the_simulator(GRAPH)
    assert not bad, (
        "procedures reach the lab through drivers only (of sim, only "
        f"{', '.join(PURE_SIM)}); chains into the simulator:{listing(bad)}"
    )


def matplotlib_imports(path: Path) -> list[int]:
    """Lines of ``path`` importing matplotlib (at any level: module, function)."""
    lines = []
    for n in ast.walk(ast.parse(path.read_text(), str(path))):
        names = ([a.name for a in n.names] if isinstance(n, ast.Import)
                 else [n.module or ""] if isinstance(n, ast.ImportFrom) and not n.level else [])
        if any(x == "matplotlib" or x.startswith("matplotlib.") for x in names):
            lines.append(n.lineno)
    return lines


def test_procedures_draw_no_plots(tmp_path):
    """Plots are the application's (laboratory/, drawn by the plot child): no procedure
    imports matplotlib, not even inside a function."""
    bad = {str(p.relative_to(ROOT)): hits for p in python_files("procedures")
           if (hits := matplotlib_imports(p))}
    assert not bad, f"procedures importing matplotlib: {bad}"
    toy = tmp_path / "toy.py"
    toy.write_text("def f():\n    import matplotlib.pyplot as plt\n    from matplotlib import cm\n")
    assert matplotlib_imports(toy) == [2, 3]


def test_drivers_import_neither_sim_nor_instruments():
    for p in LAB_BOUNDARY:
        assert any(m.startswith(p + ".") for m in MODULES), f"no modules in {p}: vacuous check"
    bad = direct_lab_imports(GRAPH, LAB_BOUNDARY)
    assert not bad, f"drivers reach the lab through links only:{listing(bad)}"


def test_no_import_cycles():
    bad = import_cycles(GRAPH, MODULES)
    assert not bad, f"import cycles between modules:{listing(bad)}"


def python_files(folder: str) -> list[Path]:
    return sorted(p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts)


@pytest.mark.parametrize("folder", CLOCK_CHECKED)
def test_checked_folders_are_not_empty(folder):
    files = python_files(folder)
    assert files, f"no Python files under {folder}/: the boundary tests would pass vacuously"


@pytest.mark.parametrize("folder", CLOCK_CHECKED)
def test_no_wall_clock(folder):
    bad = {
        str(p.relative_to(ROOT)): hits
        for p in python_files(folder)
        if (hits := wall_clock_uses(p.read_text()))
    }
    assert not bad, f"{folder}/ must use the station clock, not the wall clock: {bad}"


# ----------------------------------------------------------------------------- the readers

PKG = ["procedures", "survey"]  # as if the snippet were procedures/survey/<module>.py


@pytest.mark.parametrize(
    ("source", "imports"),
    [
        ("import sim", {("sim", ())}),
        ("import sim.isu.world as w", {("sim.isu.world", ())}),
        ("import numpy, instruments.isu.counter", {("numpy", ()), ("instruments.isu.counter", ())}),
        ("from sim import units", {("sim", ("units",))}),
        ("from sim.isu.world import World, Site as S", {("sim.isu.world", ("World", "Site"))}),
        ("def f():\n    import sim.isu.pulses\n", {("sim.isu.pulses", ())}),
        ("class C:\n    def f(self):\n        from station import racks\n",
         {("station", ("racks",))}),
        ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
         "    from station.racks.isu import Station\n",
         {("typing", ("TYPE_CHECKING",)), ("station.racks.isu", ("Station",))}),
        ("from . import sheets", {("procedures.survey", ("sheets",))}),
        ("from .instruments_table import rows",
         {("procedures.survey.instruments_table", ("rows",))}),
        ("from ..runner import Run", {("procedures.runner", ("Run",))}),
        ("from ... import sim", {("", ("sim",))}),  # relative, climbing out of procedures/
        ("from sim.units import *", {("sim.units", ())}),
        ("import importlib\nm = importlib.import_module('sim.isu.world')",
         {("importlib", ()), ("sim.isu.world", ())}),
        ("from importlib import import_module\nimport_module('instruments')",
         {("importlib", ("import_module",)), ("instruments", ())}),
        ("import importlib as il\nil.import_module(name='instruments.isu.ieu')",
         {("importlib", ()), ("instruments.isu.ieu", ())}),
        ("import importlib\nm = importlib.import_module('.world', 'sim.isu')",
         {("importlib", ()), ("sim.isu.world", ())}),
        ("import importlib\nm = importlib.import_module('.sheets')",
         {("importlib", ()), ("procedures.survey.sheets", ())}),
        ("m = __import__('sim')", {("sim", ())}),
        ("import importlib\nm = importlib.import_module(name)", {("importlib", ())}),
        ("x = 'import sim'", set()),
    ],
)
def test_import_reader(source, imports):
    assert {(i.module, i.names) for i in imported_names(source, PKG)} == imports


def test_import_reader_marks_typing_only_imports():
    src = (
        "from typing import TYPE_CHECKING\nimport typing\nif TYPE_CHECKING:\n"
        "    import sim.a\nelse:\n    import sim.b\nif typing.TYPE_CHECKING:\n    import sim.c\n"
    )
    got = {i.module: (i.line, i.typing_only) for i in imported_names(src, PKG) if "sim" in i.module}
    assert got == {"sim.a": (4, True), "sim.b": (6, False), "sim.c": (8, True)}


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


# ----------------------------------------------------------------------------- the rules, on a toy


def toy_tree(root: Path, files: dict[str, str]
             ) -> tuple[dict[str, Path], dict[str, dict[str, Edge]]]:
    """A project of the given files (path -> source), every folder a package."""
    for rel, src in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(src)
        for d in p.relative_to(root).parents:
            if str(d) != ".":
                (root / d / "__init__.py").touch()
    return import_graph(root, FLOORS)


def test_toy_floors(tmp_path):
    _, g = toy_tree(tmp_path, {
        "sim/world.py": "",
        "instruments/base.py": "from sim import world\n",
        "station/rack.py": "import instruments.base\n",
        "station/drivers/table.py": "from typing import TYPE_CHECKING\n"
                                    "if TYPE_CHECKING:\n    from procedures.day import Day\n",
        "procedures/day.py": "def run():\n    from laboratory.cli import main\n",
        "laboratory/cli.py": "from procedures import day\n",
    })
    assert upward_imports(g) == [
        "procedures.day (line 2) imports laboratory.cli: laboratory is above procedures",
        "station.drivers.table (line 3, typing only) imports procedures.day: "
        "procedures is above station",
    ]


def test_toy_procedures_reaching_the_simulator(tmp_path):
    _, g = toy_tree(tmp_path, {
        "sim/units.py": "",
        "sim/timebase.py": "from sim import units\n",
        "sim/world.py": "",
        "instruments/base.py": "",
        "station/clock.py": "from sim.timebase import ticks\n",
        "station/racks/isu.py": "from instruments.base import ByteInstrument\n",
        "station/drivers/table.py": "from station.clock import Clock\n",
        "procedures/ok.py": "from sim import units\nfrom station.drivers import table\n",
        "procedures/typed.py": "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n"
                               "    from station.racks.isu import Station\n",
        "procedures/day.py": "from . import typed\n",
        "procedures/direct.py": "import importlib\nW = importlib.import_module('sim.world')\n",
    })
    assert procedures_reaching_the_simulator(g) == [
        "procedures.day (line 1) -> procedures.typed (line 4, typing only) -> "
        "station.racks.isu (line 1) -> instruments.base",
        "procedures.direct (line 2) -> sim.world",
        "procedures.typed (line 4, typing only) -> station.racks.isu (line 1) -> instruments.base",
    ]


def test_toy_cycles(tmp_path):
    modules, g = toy_tree(tmp_path, {
        "station/hil/__init__.py": "from station.hil import server, status\n",  # own children
        "station/hil/server.py": "from station.hil import status\n",
        "station/hil/status.py": "def f():\n    from station.hil.link import Link\n",
        "station/hil/link.py": "from station.hil.server import Server\n",
        "station/hil/other.py": "from station.hil import link\n",
        "laboratory/a.py": "from . import b\n",
        "laboratory/b.py": "from . import a\n",
    })
    assert import_cycles(g, modules) == [
        "laboratory.a (line 1) -> laboratory.b (line 1) -> laboratory.a",
        "station.hil.link (line 1) -> station.hil.server (line 1) -> "
        "station.hil.status (line 2) -> station.hil.link",
    ]


def test_toy_package_init_importing_its_children_is_no_cycle(tmp_path):
    modules, g = toy_tree(tmp_path, {
        "procedures/calibration/__init__.py": "from procedures.calibration.compute import run\n",
        "procedures/calibration/compute.py": "from procedures.calibration.inputs import Data\n",
        "procedures/calibration/inputs.py": "",
    })
    assert import_cycles(g, modules) == []
    # a child's import of a sibling loads its own package first: not an edge to the package
    assert set(g["procedures.calibration.compute"]) == {"procedures.calibration.inputs"}
