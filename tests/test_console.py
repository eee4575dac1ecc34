"""Console and plots (issue 15): at 80 columns no table cell of the day is cut, piped
`station compare` keeps every key whole, help texts keep their [cigtf]/[esg], and the plots
carry their labels, units, error bars and the fitted Q_II."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from laboratory.cigtf import gyrocompassing  # noqa: E402
from laboratory.esg import calibration as esg_calibration  # noqa: E402
from laboratory.isu import plots  # noqa: E402
from procedures.esg.calibration import ScheduleResult  # noqa: E402


def station(*args: str, columns: int = 80) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, COLUMNS=str(columns))
    return subprocess.run([sys.executable, "-m", "laboratory.cli", *args], env=env,
                          capture_output=True, text=True, check=False)


@pytest.fixture(scope="module")
def day80(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("console") / "day"
    p = station("day", "--only", "II-11", "--positions", "7", "--out", str(out))
    assert p.returncode == 0, p.stderr
    return out, p.stdout


def test_day_at_80_columns_cuts_no_cell(day80: tuple[Path, str]) -> None:
    out, text = day80
    assert "\u2026" not in text  # no ellipsis anywhere: no cell, no step line cut
    # the closing line names the run directory, as long as the machine makes it (a worker's
    # tmp path under xdist): measured as "DIR"
    assert max(len(line) for line in text.replace(str(out), "DIR").splitlines()) <= 80
    res = json.loads((out / "results.json").read_text())
    shown = 0
    for r in res["calibration"]:  # every number is shown whole
        for key, fmt in (("truth", ".8g"), ("estimate", ".8g")):
            if r[key] is not None:
                assert format(r[key], fmt) in text, (r["instrument"], r["parameter"], key)
                shown += 1
    assert shown > 50
    for e in res["alignment"]:
        assert "/".join(f"{x:.2f}" for x in e["physical_limit_arcsec"]) in text


def test_piped_compare_shows_every_key_whole(day80: tuple[Path, str], tmp_path: Path) -> None:
    a, _ = day80
    b = tmp_path / "b"
    shutil.copytree(a, b)
    res = json.loads((b / "results.json").read_text())
    res["alignment"][0]["error_over_sigma"] = [9.0, 8.0, 7.0]
    (b / "results.json").write_text(json.dumps(res))
    p = station("compare", str(a), str(b))
    assert p.returncode == 1, p.stderr
    assert "\u2026" not in p.stdout
    for i in range(3):
        assert f"results.alignment[0].error_over_sigma[{i}]" in p.stdout


@pytest.mark.parametrize(("command", "words"), [
    ("serve", ("[cigtf]", "[esg]")),
    ("gyrocompass-test", ("[cigtf]",)),
    ("esg-calibration", ("[esg]", "[esg.pattern]", "[esg.signal]")),
])
def test_help_texts_keep_their_brackets(command: str, words: tuple[str, ...]) -> None:
    p = station(command, "--help", columns=300)
    assert p.returncode == 0, p.stderr
    for w in words:
        assert w in p.stdout
        assert "\\" + w not in p.stdout  # no markup escape left in plain help


@pytest.mark.parametrize(("args", "first"), [
    ((), "Usage: python -m laboratory.cli [OPTIONS] COMMAND"),
    (("regress",), "Usage: python -m laboratory.cli regress [OPTIONS] COMMAND"),
])
def test_a_group_without_its_command_shows_its_help(args: tuple[str, ...], first: str) -> None:
    """`station` or `station regress` alone: the group's help on stdout (exit 2, as click
    has it), not an error line."""
    p = station(*args)
    assert p.returncode == 2
    assert p.stdout.startswith(first) and "Commands:" in p.stdout
    assert p.stderr == ""


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    """The figures the plot functions close (kept to read their texts back)."""
    kept: list[Figure] = []
    close = plt.close

    def keep(fig: Any = None) -> None:
        if isinstance(fig, Figure):
            kept.append(fig)
        else:
            close(fig)

    monkeypatch.setattr(plt, "close", keep)
    return kept


def _texts(fig: Figure) -> list[str]:
    out = [fig.get_suptitle()] if hasattr(fig, "get_suptitle") else []
    for ax in fig.axes:
        out += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
        leg = ax.get_legend()
        if leg is not None:
            out += [t.get_text() for t in leg.get_texts()]
        out += [t.get_text() for t in ax.texts]
    return [t for t in out if t]


def _non_blank(path: Path) -> None:
    img = plt.imread(path)
    assert img.shape[0] > 200 and img.shape[1] > 400
    assert float(np.std(img[..., :3])) > 0.01


def test_nonlinearity_plot_has_error_bars_and_q_ii(figures: list[Figure],
                                                   tmp_path: Path) -> None:
    a1, q = 1 / 3.0, 2e-9  # pulses/s per deg/hr (3 arcsec/pulse), hr/deg
    rows = []
    for rate in (-15.0, -10.0, -5.0, 5.0, 10.0, 15.0):
        w = rate * 3600.0
        p = a1 * w + a1 * q * w * w
        rows.append({"w_deg_hr": w, "p_dot": p, "counts": p * 80.0, "rate_deg_s": rate})
    path = tmp_path / "nl.png"
    plots.nonlinearity_plot({1: rows, 2: rows}, path)
    (fig,) = figures
    texts = _texts(fig)
    assert any(t.startswith("fit: Q_II = 2e-09 +/- ") and t.endswith("hr/deg") for t in texts)
    assert "total rate w (10^3 deg/hr)" in texts and "output frequency P' (kpulses/s)" in texts
    assert sum(len(ax.containers) for ax in fig.axes) == 4  # error bars on every panel
    _non_blank(path)


def test_series_scale_factor_is_the_gyros_within_a_part_in_a_thousand() -> None:
    """The nonlinearity plot's DeltaPhi from the II-7 series alone (drawn before Chart
    II-15 has one): a drawn scale factor, bias and Q_II at the series' rates."""
    rng = np.random.default_rng(17)
    for _ in range(20):
        dphi = rng.uniform(1.0, 6.0)  # arcsec/pulse
        bias, q = rng.uniform(-20.0, 20.0), rng.uniform(-5e-9, 5e-9)  # deg/hr, hr/deg
        w = np.array([-15.0, -10.0, -5.0, 5.0, 10.0, 15.0]) * 3600.0
        p = (w + bias + q * w * w) / dphi
        assert plots.series_dphi_arcsec(w, p) == pytest.approx(dphi, rel=1e-3)


def test_results_plot_error_over_sigma_or_limits(figures: list[Figure], tmp_path: Path) -> None:
    rows = [{"instrument": "gyro1", "parameter": "R", "units": "deg/hr", "estimate": 0.51,
             "truth": 0.5, "error": 0.01, "sigma": 0.005, "limit": 0.02},
            {"instrument": "gyro1", "parameter": "J", "units": "hr", "estimate": None,
             "truth": 1e-6, "error": None, "sigma": None, "limit": None}]
    assert plots.results_plot(rows, tmp_path / "sim.png")
    assert "error / predicted sigma (truth check, simulation only)" in _texts(figures[-1])
    real = [dict(r, truth=None, error=None) for r in rows]
    assert plots.results_plot(real, tmp_path / "real.png")
    assert "|estimate| / acceptance limit" in _texts(figures[-1])
    assert "gyro1 R (deg/hr)" in _texts(figures[-1])
    # one bar, from 0 to |estimate| / limit, beside its name (row 0)
    (bars,) = figures[-1].axes[0].collections
    (bar,) = bars.get_paths()
    xs, ys = bar.vertices[:, 0], bar.vertices[:, 1]
    assert (xs.min(), xs.max()) == pytest.approx((0.0, 0.51 / 0.02))
    assert (ys.min(), ys.max()) == pytest.approx((-0.4, 0.4))
    assert not plots.results_plot([dict(r, truth=None, error=None, limit=None) for r in rows],
                                  tmp_path / "none.png")
    _non_blank(tmp_path / "sim.png")


def test_gyrocompass_plot_numbers_runs_as_the_table(figures: list[Figure],
                                                    tmp_path: Path) -> None:
    runs = [{"phase": "operating", "run": i, "theta_arcsec": 1.0, "sigma_arcsec": 2.0}
            for i in range(1, 26)]
    runs += [{"phase": "shutdown", "run": i, "theta_arcsec": 2.0, "sigma_arcsec": 2.0}
             for i in range(1, 11)]
    res = {"runs": runs, "phases": [{"phase": "operating", "theta_arcsec": 1.0},
                                    {"phase": "shutdown", "theta_arcsec": 2.0}],
           "truth": {"theta_arcsec": 1.5}}
    gyrocompassing.theta_plot(res, tmp_path / "g.png")
    (fig,) = figures
    shut = fig.axes[1]
    xs = shut.containers[0].lines[0].get_xdata()
    assert list(xs) == list(range(1, 11))
    assert "gyrocompassing error theta (arcsec)" in _texts(fig)
    _non_blank(tmp_path / "g.png")


def test_esg_plot_labels_goal_lines_and_keeps_the_legend_outside(
        figures: list[Figure], tmp_path: Path) -> None:
    rows = [{"colatitude_deg": c, "error_arcsec": 3.0, "true_error_arcsec": 2.0}
            for c in (45.0, 90.0, 135.0)]
    res = ScheduleResult("5deg", None, rows, rows)  # type: ignore[arg-type]  # no fit drawn
    esg_calibration.calibration_plot([res], tmp_path / "e.png")
    (fig,) = figures
    texts = _texts(fig)
    assert "+15 arcsec goal" in texts and "-15 arcsec goal" in texts
    assert "goal +/-15 arcsec" in texts
    ax = fig.axes[0]
    fig.canvas.draw()
    leg = ax.get_legend().get_window_extent()
    assert leg.x0 >= ax.get_window_extent().x1  # right of the axes: no point hidden
    assert ax.get_xlabel() == "colatitude of pickoff 2 (deg)"
    _non_blank(tmp_path / "e.png")
