"""run.json's VCS revision (laboratory.vcs): HEAD, -dirty with changes to tracked files, None
outside a checkout or when git fails; the same whether git was asked as the command line
named the run (``start``) or when the run asks."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from laboratory import vcs
from laboratory.identity import vcs_revision


def _git(tree: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(tree), "-c", "user.name=t", "-c",
                           "user.email=t@example.org", *args],
                          capture_output=True, text=True, check=True).stdout.strip()


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    _git(tmp_path, "init", "-q")
    (tmp_path / "a.txt").write_text("one\n")
    _git(tmp_path, "add", "a.txt")
    _git(tmp_path, "commit", "-q", "-m", "first")
    return tmp_path


def test_the_revision_is_head_and_dirty_only_with_tracked_changes(tree: Path) -> None:
    head = _git(tree, "rev-parse", "HEAD")
    assert len(head) == 40
    assert vcs.revision(tree) == head
    (tree / "new.txt").write_text("untracked\n")  # untracked files do not count
    assert vcs.revision(tree) == head
    (tree / "a.txt").write_text("two\n")
    assert vcs.revision(tree) == head + "-dirty"
    assert vcs_revision(tree) == head + "-dirty"


def test_asked_early_it_is_the_same_and_taken_once(tree: Path) -> None:
    head = _git(tree, "rev-parse", "HEAD")
    vcs.start(tree)
    vcs.start(tree)  # a second start keeps the first answers
    assert tree in vcs._started  # noqa: SLF001
    assert vcs.revision(tree) == head
    assert tree not in vcs._started  # noqa: SLF001  # taken: the next run asks again
    (tree / "a.txt").write_text("two\n")
    assert vcs.revision(tree) == head + "-dirty"


def test_no_checkout_or_no_commit_gives_none(tmp_path: Path) -> None:
    assert vcs.revision(tmp_path) is None
    vcs.start(tmp_path)
    assert tmp_path not in vcs._started  # noqa: SLF001  # nothing asked
    _git(tmp_path, "init", "-q")  # a checkout without a commit: rev-parse HEAD fails
    assert vcs.revision(tmp_path) is None
    vcs.start(tmp_path)
    assert vcs.revision(tmp_path) is None


def test_git_missing_gives_none(tree: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", str(tree / "no-such-dir"))
    assert vcs.revision(tree) is None
