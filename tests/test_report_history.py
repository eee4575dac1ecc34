"""The report's "History of this unit" (issue 16), in headless Chromium: after three short
runs of one unit the third run's report.html shows the trend plot (it decodes) and one row
per constant whose z is `station trend`'s; the first run's says in one line that there are
no earlier runs; a later run never enters an earlier run's report."""

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
# after the page has loaded: how wide the trend plot decoded (0 for a broken image)
PROBE = ("<script>window.addEventListener('load', () => {const i = document.getElementById("
         "'history-plot'); document.body.setAttribute('data-plot-width', i ? "
         "String(i.naturalWidth) : 'none');});</script>")


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
    text, the trend table's rows and cells, and the plot's decoded width."""

    def __init__(self) -> None:
        super().__init__()
        self.shown: str | None = None
        self.none_text = ""
        self.plot_width: str | None = None
        self.plot_src = ""
        self.rows: dict[str, list[str]] = {}
        self._in_table = False
        self._row: list[str] | None = None
        self._cell = False
        self._in_none = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "body":
            self.plot_width = a.get("data-plot-width")
        elif tag == "section" and a.get("id") == "history":
            self.shown = a.get("data-shown")
        elif tag == "p" and a.get("id") == "history-none":
            self._in_none = True
        elif tag == "img" and a.get("id") == "history-plot":
            self.plot_src = str(a.get("src"))
        elif tag == "table" and a.get("data-table") == "trend":
            self._in_table = True
        elif tag == "tr" and self._in_table and a.get("data-row"):
            self._row = self.rows.setdefault(str(a["data-row"]), [])
        elif tag == "td" and self._row is not None:
            self._row.append("")
            self._cell = True

    def handle_endtag(self, tag: str) -> None:
        if tag == "table":
            self._in_table = False
        elif tag == "tr":
            self._row = None
        elif tag == "td":
            self._cell = False
        elif tag == "p":
            self._in_none = False

    def handle_data(self, data: str) -> None:
        if self._in_none:
            self.none_text += data
        if self._cell and self._row is not None:
            self._row[-1] += data


def rendered(report: Path, tmp: Path) -> Dom:
    """The report as Chromium builds it, with the plot's naturalWidth read after load."""
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


def test_the_third_run_shows_its_history(runs: dict, tmp_path: Path) -> None:
    dom = rendered(runs["days"][2] / "report.html", tmp_path)
    assert dom.shown == "yes"
    assert dom.plot_src.startswith("data:image/png;base64,")  # self-contained
    assert dom.plot_width is not None and int(dom.plot_width) > 0  # the PNG decodes
    z = trend_z(runs["trend"])
    assert len(z) >= 12  # II-6 determines DeltaPhi and G.B1-3 of each gyro
    assert sorted(dom.rows) == sorted(z)
    for name, cells in dom.rows.items():
        assert cells[3] == "3", name  # three calibrations: this run and two before it
        assert cells[5] == z[name], name  # `station trend`'s z of the latest change


def test_station_trend_html_is_the_same_section(runs: dict) -> None:
    """`station trend UNIT --html FILE`: the section on a page of its own, the same rows."""
    page, report = Dom(), Dom()
    page.feed((runs["base"] / "trend.html").read_text(encoding="utf-8"))
    report.feed((runs["days"][2] / "report.html").read_text(encoding="utf-8"))
    assert page.shown == "yes" and page.plot_src.startswith("data:image/png;base64,")
    assert page.rows == report.rows


def test_the_first_run_has_no_earlier_runs(runs: dict, tmp_path: Path) -> None:
    dom = rendered(runs["days"][0] / "report.html", tmp_path)
    assert dom.shown == "no" and dom.plot_width == "none" and not dom.rows
    assert dom.none_text == (f"No earlier runs of {UNIT} in the calibration history: this "
                             "is its first; nothing to trend yet.")


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
