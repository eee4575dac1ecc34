"""The report's "History of this unit" (issue 16), in headless Chromium: after three short
runs of one unit the third run's report.html shows one row per constant whose z is `station
trend`'s, each with an SVG sparkline of its three calibrations in the order of their
estimates; the first run's says in one line that there are no earlier runs; a later run never
enters an earlier run's report; building the report never imports matplotlib."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DAY = ["day", "--only", "II-6", "--quiet"]  # the gyros' II-6 constants, under a second each
UNIT = "ISU-000-001"
# after the page has loaded: each sparkline's circles' cy as Chromium's SVG geometry reads them
# ('x' for a circle that is not an SVG element), and how many sparklines there are
PROBE = ("<script>window.addEventListener('load', () => {const s = document.querySelectorAll("
         "'#history svg'); for (const g of s) {g.setAttribute('data-cy', Array.from("
         "g.querySelectorAll('circle')).map(c => c instanceof SVGCircleElement ? "
         "String(c.cy.baseVal.value) : 'x').join(' '));} document.body.setAttribute("
         "'data-sparklines', String(s.length));});</script>")


def station(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """`station ARGS` in a subprocess, the history where the run lies (no URL set)."""
    env = {k: v for k, v in os.environ.items() if k != "STATION_HISTORY_URL"}
    env["COLUMNS"] = "200"  # `station trend` in one table
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


def browser() -> str:
    """Chromium by name; skipped without one (.ci/run installs Debian's package)."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no chromium on this machine (.ci/run installs it: apt-get install chromium)")


class Dom(HTMLParser):
    """What the test reads of the rendered DOM: the history section's state and one-line
    text, the trend table's rows and cells (the sparkline's title apart), and per row its
    sparklines: title, circles (cy as written, classes) and the probe's cy."""

    def __init__(self) -> None:
        super().__init__()
        self.shown: str | None = None
        self.none_text = ""
        self.sparklines: str | None = None  # the probe's count; None without the probe
        self.rows: dict[str, list[str]] = {}
        self.sparks: dict[str, list[dict]] = {}
        self.svgs = 0  # every <svg> in the document
        self._in_table = False
        self._row: list[str] | None = None
        self._label = ""
        self._cell = False
        self._in_none = False
        self._in_title = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "body":
            self.sparklines = a.get("data-sparklines")
        elif tag == "section" and a.get("id") == "history":
            self.shown = a.get("data-shown")
        elif tag == "p" and a.get("id") == "history-none":
            self._in_none = True
        elif tag == "table" and a.get("data-table") == "trend":
            self._in_table = True
        elif tag == "tr" and self._in_table and a.get("data-row"):
            self._label = str(a["data-row"])
            self._row = self.rows.setdefault(self._label, [])
        elif tag == "td" and self._row is not None:
            self._row.append("")
            self._cell = True
        elif tag == "svg":
            self.svgs += 1
            if self._row is not None:
                self.sparks.setdefault(self._label, []).append(
                    {"title": "", "cy": [], "classes": [], "probe": a.get("data-cy")})
        elif tag == "title" and self._row is not None:
            self._in_title = True
        elif tag == "circle" and self._row is not None:
            self.sparks[self._label][-1]["cy"].append(float(str(a["cy"])))
            self.sparks[self._label][-1]["classes"].append(a.get("class"))

    def handle_endtag(self, tag: str) -> None:
        if tag == "table":
            self._in_table = False
        elif tag == "tr":
            self._row = None
        elif tag == "td":
            self._cell = False
        elif tag == "p":
            self._in_none = False
        elif tag == "title":
            self._in_title = False

    def handle_data(self, data: str) -> None:
        if self._in_none:
            self.none_text += data
        if self._in_title and self._row is not None:
            self.sparks[self._label][-1]["title"] += data
        elif self._cell and self._row is not None:
            self._row[-1] += data


def rendered(report: Path, tmp: Path) -> Dom:
    """The report as Chromium builds it, with the sparklines' geometry read after load."""
    page = tmp / f"probe-{report.parent.name}.html"
    page.write_text(report.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"),
                    encoding="utf-8")
    p = subprocess.run([browser(), "--headless", "--no-sandbox", "--disable-gpu",
                        "--no-first-run", "--disable-extensions", "--virtual-time-budget=5000",
                        "--dump-dom", page.as_uri()],
                       capture_output=True, text=True, timeout=300, check=True)
    dom = Dom()
    dom.feed(p.stdout)
    return dom


def trend_z(stdout: str) -> dict[str, str]:
    """`station trend`'s z per constant ("gyro1 R": "+0.52"), read from its table."""
    z = {}
    for line in stdout.splitlines():
        m = re.match(r"\s*(\S+)\s+(\S+)\s+(\S+)\s+(\d+)\s+([+-]\S+e\S+)\s+([+-]\d+\.\d\d)\s",
                     line)
        if m:
            z[f"{m[1]} {m[2]}"] = m[6]
    return z


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Three runs of one unit (seeds 1-3) under a runs directory, indexed at their ends;
    `station trend` then; then a fourth run (seed 4) and the third's report made again."""
    base = tmp_path_factory.mktemp("report_history")
    days = []
    for seed in (1, 2, 3):
        out = base / "runs" / f"day{seed}"
        p = station(*DAY, "--seed", str(seed), "--out", str(out))
        assert p.returncode == 0 and "warning" not in p.stderr, p.stderr
        days.append(out)
    t = station("trend", UNIT, "--db", str(base / "runs" / "history.sqlite"), "--plot",
                str(base / "trend.png"), "--html", str(base / "trend.html"))
    assert t.returncode == 0, t.stdout + t.stderr
    fourth = base / "runs" / "day4"
    assert station(*DAY, "--seed", "4", "--out", str(fourth)).returncode == 0
    again = base / "again.html"
    r = station("report", str(days[2]), "--out", str(again))
    assert r.returncode == 0, r.stderr
    return {"base": base, "days": days, "trend": t.stdout, "fourth": fourth, "again": again}


def estimates(days: list[Path]) -> dict[str, list[float]]:
    """Per constant ("gyro1 R") its estimate on each of ``days``, from their records."""
    from laboratory.history.store import result_rows

    out: dict[str, list[float]] = {}
    for d in days:
        for r in result_rows(d):
            if r.get("estimate") is not None and (r.get("sigma") or 0) > 0:
                name = f"{r.get('instrument') or ''} {r['parameter']}".strip()
                out.setdefault(name, []).append(float(r["estimate"]))
    return out


def test_the_third_run_shows_its_history(runs: dict, tmp_path: Path) -> None:
    dom = rendered(runs["days"][2] / "report.html", tmp_path)
    assert dom.shown == "yes"
    z = trend_z(runs["trend"])
    assert len(z) >= 12  # II-6 determines DeltaPhi and G.B1-3 of each gyro
    assert sorted(dom.rows) == sorted(z)
    assert dom.svgs == len(z) and dom.sparklines == str(len(z))  # one svg per row, no plot
    est = estimates(runs["days"])
    for name, cells in dom.rows.items():
        assert cells[3] == "3", name  # three calibrations: this run and two before it
        assert cells[5] == z[name], name  # `station trend`'s z of the latest change
        [spark] = dom.sparks[name]
        x = est[name]
        assert len(x) == 3 and spark["title"].startswith(
            f"{name} (") and "3 calibrations oldest first (the last is this run)" in spark[
            "title"] and spark["title"].count("±") == 3, spark["title"]
        cy = [float(v) for v in spark["probe"].split()]  # as Chromium's SVG geometry reads it
        assert cy == pytest.approx(spark["cy"], abs=1e-5), name  # Chromium's float32
        assert spark["classes"] == [None, None, "now"], name  # this run marked
        # larger estimates higher up (smaller cy): the order of the estimates, top down
        top_down = sorted(range(3), key=lambda i: -x[i])
        assert [cy[i] for i in top_down] == sorted(cy), (name, x, cy)
        assert cy[top_down[0]] < cy[top_down[-1]], (name, x, cy)


def test_station_trend_html_is_the_same_section(runs: dict) -> None:
    """`station trend UNIT --html FILE`: the section on a page of its own, the same rows
    and sparklines (whose last point is the latest calibration there)."""
    page, report = Dom(), Dom()
    page.feed((runs["base"] / "trend.html").read_text(encoding="utf-8"))
    report.feed((runs["days"][2] / "report.html").read_text(encoding="utf-8"))
    assert page.shown == "yes" and page.rows == report.rows and page.rows
    for name, [spark] in page.sparks.items():
        [ours] = report.sparks[name]
        assert spark["cy"] == ours["cy"] and spark["title"] == ours["title"].replace(
            "the last is this run", "the last is the latest"), name
    assert (runs["base"] / "trend.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # still drawn


def test_the_first_run_has_no_earlier_runs(runs: dict, tmp_path: Path) -> None:
    dom = rendered(runs["days"][0] / "report.html", tmp_path)
    assert dom.shown == "no" and dom.sparklines == "0" and not dom.rows and not dom.svgs
    assert dom.none_text == (f"No earlier runs of {UNIT} in the calibration history: this "
                             "is its first; nothing to trend yet.")


def test_the_report_with_history_never_imports_matplotlib(runs: dict) -> None:
    """Building the report of a run with a history leaves matplotlib unimported: the
    sparklines are SVG markup written in Python."""
    code = ("import sys; from pathlib import Path; from laboratory.report import "
            "render_report; html = render_report(Path(sys.argv[1])); "
            "print(html.count('<svg class=\"spark\"'), 'matplotlib' in sys.modules)")
    p = subprocess.run([sys.executable, "-c", code, str(runs["days"][2])], cwd=ROOT,
                       env={k: v for k, v in os.environ.items() if k != "STATION_HISTORY_URL"},
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert p.stdout == f"{len(trend_z(runs['trend']))} False\n"


def test_a_later_run_stays_out_of_an_earlier_report(runs: dict) -> None:
    """The third run's report made again after a fourth run: still its three runs; the
    fourth run's own report counts four."""
    def counts(report: Path) -> set[str]:
        dom = Dom()
        dom.feed(report.read_text(encoding="utf-8"))
        return {cells[3] for cells in dom.rows.values()}

    assert counts(runs["again"]) == {"3"}
    assert counts(runs["fourth"] / "report.html") == {"4"}
    same = Dom()
    same.feed((runs["days"][2] / "report.html").read_text(encoding="utf-8"))
    again = Dom()
    again.feed(runs["again"].read_text(encoding="utf-8"))
    assert again.rows == same.rows


def test_without_a_history_the_section_is_one_line(tmp_path: Path) -> None:
    """A run under no runs directory (no URL set) and a history that cannot be opened:
    the report is written, its section says so in one line."""
    from laboratory.history.section import safe_history_section

    out = tmp_path / "alone"
    p = station(*DAY, "--positions", "1", "--seed", "1", "--out", str(out))
    assert p.returncode == 0 and p.stderr == "", p.stderr
    dom = Dom()
    dom.feed((out / "report.html").read_text(encoding="utf-8"))
    assert dom.shown == "no" and dom.none_text.startswith(
        "No history: the calibration history is off for this run")
    bad = safe_history_section(out, "nosuchdialect://x")
    assert bad == {"shown": False, "text": "No history: the calibration history cannot be "
                   "read: history database nosuchdialect://x: Can't load plugin: "
                   "sqlalchemy.dialects:nosuchdialect"}
