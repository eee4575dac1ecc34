"""The whole project type-checks: mypy, configured in pyproject.toml ([tool.mypy]), reports no
error on sim, instruments, station, procedures and laboratory. Run inside the suite so that
the README's one test command (and .ci/run) checks types too."""

from __future__ import annotations

import os
from pathlib import Path

from mypy import api

REPO = Path(__file__).resolve().parents[1]


def test_mypy_is_clean_on_the_whole_project(tmp_path):
    cwd = os.getcwd()
    os.chdir(REPO)  # the config's package list is relative to the repository
    try:
        out, err, status = api.run(["--config-file", str(REPO / "pyproject.toml"),
                                    "--cache-dir", str(tmp_path / "mypy-cache")])
    finally:
        os.chdir(cwd)
    assert status == 0, out + err
    assert out.startswith("Success: no issues found"), out
