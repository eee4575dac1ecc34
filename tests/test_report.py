"""`station report` and the report.html every run command writes, tested in a real browser.

Four runs through the command line (a short day, a level alignment, the CIGTF gyrocompass
test, the ESG calibration); headless Chromium (Debian's `chromium`, installed by .ci/run)
loads each report.html from file://, the test reads the DOM it built for the verdict and
every result row, and looks at a screenshot for its size and non-blank content.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

RUNS = {
    "day": ["day", "--only", "II-11", "--positions", "7", "--quiet"],
    "align": ["align", "--method", "level", "--quiet"],
    "gyrocompass": ["gyrocompass-test"],
    "esg": ["esg-calibration"],
}
RESULTS = {"day": "results.json", "align": "results.json", "gyrocompass": "gyrocompass.json",
           "esg": "esg.json"}
SHOT = (1280, 2000)  # screenshot width, height in pixels


def browser() -> str:
    """The Chromium binary by name; the test is skipped on a machine without one (.ci/run
    installs Debian's package)."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no chromium on this machine (.ci/run installs it: apt-get install chromium)")


def chromium(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([browser(), "--headless", "--no-sandbox", "--disable-gpu",
                           "--no-first-run", "--disable-extensions", *args],
                          capture_output=True, text=True, timeout=300, check=True)


class Dom(HTMLParser):
    """The parts of the rendered DOM the test reads: result rows by table, the verdict,
    images and their sources."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: dict[tuple[str, str], list[str]] = {}
        self.cells: dict[tuple[str, str, str], list[str]] = {}
        self.verdict: str | None = None
        self.verdict_text = ""
        self.images: list[str] = []
        self._table: tuple[str, str] | None = None
        self._row: str | None = None
        self._in_verdict = False
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "table" and a.get("data-table"):
            self._table = (str(a.get("data-kind")), str(a["data-table"]))
            self.rows.setdefault(self._table, [])
        elif tag == "tr" and self._table is not None and a.get("data-row") is not None:
            self._row = str(a["data-row"])
            self.rows[self._table].append(self._row)
            self.cells[(*self._table, self._row)] = []
        elif tag == "td" and self._row is not None and self._table is not None:
            self._cell = self.cells[(*self._table, self._row)]
            self._cell.append("")
        elif a.get("id") == "verdict":
            self.verdict = a.get("data-outcome")
            self._in_verdict = True
        elif tag == "img":
            self.images.append(str(a.get("src")))

    def handle_endtag(self, tag: str) -> None:
        if tag == "table":
            self._table = None
        elif tag == "tr":
            self._row = None
        elif tag == "td":
            self._cell = None
        elif tag == "div":
            self._in_verdict = False

    def handle_data(self, data: str) -> None:
        if self._in_verdict:
            self.verdict_text += data
        if self._cell is not None:
            self._cell[-1] += data


def expected_rows(kind: str, res: dict) -> dict[tuple[str, str], list[str]]:
    """Every result row of a record, by (table kind, table) in record order, named as the
    report names them (label fields joined)."""
    if kind in ("day", "align"):
        out = {("alignment", "alignment"): [f"{e['method']} {e['estimator']}"
                                            for e in res["alignment"]]}
        if isinstance(res["calibration"], list):
            out[("result", "calibration")] = [f"{r['instrument']} {r['parameter']}"
                                              for r in res["calibration"]]
        return out
    if kind == "gyrocompass":
        return {("result", "runs"): [f"{r['phase']} {r['run']}" for r in res["runs"]],
                ("result", "phases"): [r["phase"] for r in res["phases"]],
                ("result", "tests"): [r["name"] for r in res["tests"]]}
    return {("result", "schedules"): [s["name"] for s in res["schedules"]]}


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The four runs, each through `python -m laboratory.cli` into its own directory."""
    base = tmp_path_factory.mktemp("report_runs")
    out = {}
    for kind, argv in RUNS.items():
        d = base / kind
        p = subprocess.run([sys.executable, "-m", "laboratory.cli", *argv, "--out", str(d)],
                           capture_output=True, text=True)
        assert p.returncode in (0, 3), p.stderr  # 3: completed with a FAILED verdict
        out[kind] = d
    return out


@pytest.mark.parametrize("kind", list(RUNS))
def test_report_in_chromium(runs: dict[str, Path], kind: str) -> None:
    d = runs[kind]
    report = d / "report.html"
    assert report.is_file(), f"`station {RUNS[kind][0]}` wrote no report.html"
    html = report.read_text(encoding="utf-8")
    # self-contained: nothing fetched from anywhere, images inline
    assert "http://" not in html and "https://" not in html
    assert "@media print" in html
    res = json.loads((d / RESULTS[kind]).read_text())

    dom = Dom()
    dom.feed(chromium("--dump-dom", report.as_uri()).stdout)
    outcome = (res.get("verdict") or {}).get("outcome") or "none"
    assert dom.verdict == outcome
    assert dom.verdict_text.startswith("Verdict:")
    for table, labels in expected_rows(kind, res).items():
        assert dom.rows.get(table) == labels, table
    if kind == "day":  # the estimate of every determined constant, as the record holds it
        for r in res["calibration"]:
            if r["estimate"] is not None:
                cells = dom.cells[("result", "calibration", f"{r['instrument']} "
                                   f"{r['parameter']}")]
                assert format(r["estimate"], ".8g") in cells
    if kind in ("gyrocompass", "esg"):  # the run's PNGs, inline
        pngs = sorted(p.name for p in d.glob("*.png"))
        assert pngs and len([s for s in dom.images if s.startswith("data:image/png;base64,")]
                            ) == len(pngs)
        # the simulation's truth check is its own section, apart from the verdict
        assert "Simulation's truth check" in html

    shot = d / "report.png"
    chromium(f"--window-size={SHOT[0]},{SHOT[1]}", f"--screenshot={shot}", report.as_uri())
    import matplotlib.image as mpimg
    import numpy as np

    img = mpimg.imread(shot)
    assert img.shape[:2] == (SHOT[1], SHOT[0])
    colours = np.unique((img[..., :3] * 255).round().astype(np.uint8).reshape(-1, 3), axis=0)
    assert len(colours) > 50  # text, table shading, the verdict box: not a blank page
    # not one colour over (nearly) the whole page either
    dominant = np.mean(np.all(img[..., :3] == img[0, 0, :3], axis=-1))
    assert dominant < 0.97


def test_report_command_and_a_record_without_identity(runs: dict[str, Path],
                                                      tmp_path: Path) -> None:
    """`station report RUN_DIR --out FILE` renders from the files alone; a record of a run
    that never got its results (or run.json) still renders, saying what is missing."""
    part = tmp_path / "stopped"
    part.mkdir()
    shutil.copy(runs["gyrocompass"] / "journal.jsonl", part / "journal.jsonl")
    shutil.copytree(runs["gyrocompass"] / "sheets", part / "sheets")
    out = tmp_path / "r.html"
    p = subprocess.run([sys.executable, "-m", "laboratory.cli", "report", str(part), "--out",
                        str(out)], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    html = out.read_text(encoding="utf-8")
    assert "run.json: absent" in html
    assert "results: no results.json, gyrocompass.json or esg.json" in html
    assert 'data-sheet="check_4.3-R01"' in html
    assert not (part / "report.html").exists()


@pytest.mark.parametrize("args, message", [
    (["nowhere"], "RUN_DIR nowhere: no such directory"),
    (["."], "no run record there"),
])
def test_report_refusals(args: list[str], message: str, tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    argv = [str(tmp_path / a) if a == "nowhere" else str(empty) for a in args]
    p = subprocess.run([sys.executable, "-m", "laboratory.cli", "report", *argv],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and p.stderr.startswith("error: ")
    assert message.replace("nowhere", str(tmp_path / "nowhere")) in p.stderr


def test_a_stopped_run_has_its_report(tmp_path: Path) -> None:
    """A run that stops (a DVM falls silent mid-test) still leaves report.html: the stop, the
    completed check-sheets, no results."""
    from laboratory.cigtf.gyrocompassing import run_gyrocompass_test
    from procedures.runner import ProcedureError
    from station.racks.cigtf import CigtfRack

    def hook(rack: CigtfRack) -> None:
        def silence():  # type: ignore[no-untyped-def]
            yield rack.env.timeout(int((2 * 3600 + 4 * 950.0) * 1e9))
            rack.dvm.silent = True
        rack.env.process(silence())

    with pytest.raises(ProcedureError):
        run_gyrocompass_test(2, tmp_path, rack_hook=hook)
    html = (tmp_path / "report.html").read_text(encoding="utf-8")
    assert "stopped: " in html and "dvm" in html
    assert "results: no results.json" in html
    assert 'data-sheet="check_4.0"' in html and 'data-sheet="check_4.3-R01"' in html


def test_prepare_report_leaves_a_broken_template_to_report_after(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """prepare_report (run while the plots are drawn) raises nothing; the report that cannot
    be rendered is report_after's warning, as without it, and no report.html is left."""
    from laboratory.report import html as report_html

    def broken() -> None:
        raise OSError("templates unreadable")

    monkeypatch.setattr(report_html, "_environment", broken)
    report_html.prepare_report()
    (tmp_path / "journal.jsonl").write_text("", encoding="utf-8")
    report_html.report_after(tmp_path)
    err = capsys.readouterr().err
    assert "warning" in err and "templates unreadable" in err
    assert not (tmp_path / "report.html").exists()


def test_the_plot_child_writes_the_report_this_process_writes(
        runs: dict[str, Path], tmp_path: Path) -> None:
    """report_after with the run's plot child (`station day` ends so): the child's
    report.html has the bytes this process writes, and a child that has died leaves the
    report to this process, with the same bytes."""
    import shutil

    from laboratory.plot_worker import PlotWorker
    from laboratory.report import html as report_html

    here, child, dead = (tmp_path / n for n in ("here", "child", "dead"))
    for d in (here, child, dead):  # the same record three times, in the same-length paths
        shutil.copytree(runs["day"], d)
        (d / report_html.REPORT_NAME).unlink()
    report_html.report_after(here)
    with PlotWorker() as w:
        w.compute(report_html.PREPARE_JOB, {})
        report_html.report_after(child, w)
        assert w._outcomes[-1] == ("ok", child / report_html.REPORT_NAME)  # the child wrote it
    with PlotWorker() as w:
        assert w._proc is not None
        w._proc.kill()
        w._proc.wait()
        report_html.report_after(dead, w)

    def body(d: Path) -> str:
        return (d / report_html.REPORT_NAME).read_text(encoding="utf-8").replace(str(d), "D")

    assert str(here) in (here / report_html.REPORT_NAME).read_text(encoding="utf-8")
    assert body(child) == body(here) == body(dead)


def test_a_report_the_plot_child_cannot_write_is_a_warning(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The child's failure is met again here, and is report_after's warning as without it."""
    from laboratory.plot_worker import PlotWorker
    from laboratory.report import html as report_html

    (tmp_path / "journal.jsonl").write_text("", encoding="utf-8")
    (tmp_path / report_html.REPORT_NAME).mkdir()  # in the way of the file
    with PlotWorker() as w:
        report_html.report_after(tmp_path, w)
    assert "warning" in capsys.readouterr().err


def test_the_nonlinearity_plot_is_captioned_as_the_plot_titles_itself() -> None:
    """nonlinearity.png is Chart II-7's gyro scale-factor plot (laboratory.isu.plots'
    suptitle); the report once captioned it as an accelerometer chart (II-7Q)."""
    import inspect

    from laboratory.isu import plots
    from laboratory.report.html import PLOT_CAPTIONS

    caption = PLOT_CAPTIONS["nonlinearity.png"]
    assert f'fig.suptitle("{caption}")' in inspect.getsource(plots.nonlinearity_plot)


def test_the_journal_sheets_left_unparsed_change_no_report(runs: dict[str, Path],
                                                           tmp_path: Path) -> None:
    """build() leaves unparsed the journal's sheet records of the sheets it has from sheets/
    (issue 17): each run's report is the one from the whole journal parsed; on a made
    journal whose lines try to pass for such records (the pattern inside a sheet's data,
    an escaped name, a record with more keys, a torn line), only plain sheet records of
    the named sheets are left out and every other record is kept, in order."""
    import json

    import laboratory.report.html as h

    whole = h._journal_records
    for d in runs.values():
        got = h.build(d)
        try:
            h._journal_records = lambda d, skip_sheets=(): whole(d)  # type: ignore[assignment]
            assert got == h.build(d)
        finally:
            h._journal_records = whole
    pad = "x" * 500
    lines = [
        {"kind": "sheet", "name": "a", "data": {"v": pad}, "wall": "w"},
        {"kind": "sheet", "name": "b", "data": {"v": pad}},
        {"kind": "step", "chart": "1", "step": "2",
         "reading": {"v": pad, "tail": {"kind": "sheet", "name": "a", "wall": "w"}}},
        {"kind": "note", "event": "end", "data": {"kind": "sheet", "name": "a", "v": pad}},
        {"kind": "sheet", "name": 'a"b', "data": {"v": pad}, "wall": "w"},
        {"kind": "sheet", "name": "a", "data": {"v": pad}, "wall": "w", "zz": 1},
        {"kind": "sheet", "name": "c", "data": {"v": pad}, "wall": "w"},
    ]
    text = "\n".join(json.dumps(r, sort_keys=True, separators=(",", ":")) for r in lines)
    (tmp_path / "journal.jsonl").write_text(text + '\n{"kind":"sheet","name":"a","da')
    have = {"a", 'a"b', "c"}
    kept = whole(tmp_path, have)
    # "a" and "c" left out; "b" is not in sheets/; 'a"b' (escaped in the line) and the
    # record with a key after the stamp are parsed as before (the build ignores them)
    assert kept == lines[1:6]
