"""The source tree's git revision, for run.json: ``git rev-parse HEAD``, with ``-dirty`` when
``git status`` lists changes to tracked files; None when the package does not run from a git
checkout, and never an error.

The two git processes run side by side, and the command line starts them as it names a run
(``start``), so that they run beside the command's imports instead of one after the other
when the run writes its identity (issue 17: 4-6 ms of a run). The revision is then the
tree's as the command started, which is the code it runs.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

from laboratory.children import ended

SOURCE_TREE = Path(__file__).resolve().parent.parent
_ASKS = (("rev-parse", "HEAD"), ("status", "--porcelain", "--untracked-files=no"))
_started: dict[Path, list[subprocess.Popen[str]]] = {}


def start(tree: Path = SOURCE_TREE) -> None:
    """Ask git now; ``revision`` takes the answers (nothing when ``tree`` is no checkout)."""
    if tree not in _started:
        asked = _ask(tree)
        if asked is not None:
            _started[tree] = asked


def _ask(tree: Path) -> list[subprocess.Popen[str]] | None:
    if not (tree / ".git").exists():
        return None
    asked: list[subprocess.Popen[str]] = []
    try:
        for args in _ASKS:
            asked.append(subprocess.Popen(
                ["git", "-C", str(tree), *args], stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True))
    except (OSError, subprocess.SubprocessError):
        _ended(asked)
        return None
    return asked


def _ended(asked: list[subprocess.Popen[str]]) -> None:
    """Each process killed if it still runs, reaped, its pipe closed."""
    for p in asked:
        ended(p)


def revision(tree: Path = SOURCE_TREE) -> str | None:
    """HEAD of ``tree`` (``-dirty`` with changes) from the answers ``start`` asked for, or
    asked now; None when ``tree`` is no checkout or git fails or takes over 10 s."""
    asked = _started.pop(tree, None) or _ask(tree)
    if asked is None:
        return None
    outs = []
    try:
        for p in asked:
            out, _ = p.communicate(timeout=10)
            if p.returncode != 0:
                return None
            outs.append(out)
    except (OSError, subprocess.SubprocessError):
        return None
    finally:
        _ended(asked)
    rev = outs[0].strip()
    return (rev + ("-dirty" if outs[1].strip() else "")) or None
