"""Where generated pages come from: the checked-out commit and the date they name."""

from __future__ import annotations

import datetime
import subprocess
from pathlib import Path

#: The repository's root.
REPO = Path(__file__).resolve().parent.parent
#: The folders whose uncommitted changes a page notes.
CODE_DIRS = ("grasp_env", "agents", "configs")


def git_commit(repo: Path = REPO) -> str:
    """The checked-out commit (short hash), noting uncommitted changes to the code that
    decides the numbers (``grasp_env/``, ``agents/``, ``configs/``); ``unknown`` outside git."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=repo, capture_output=True, text=True
        )
        changed = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", *CODE_DIRS],
            cwd=repo,
            capture_output=True,
            text=True,
        )
    except OSError:
        return "unknown"
    if commit.returncode != 0:
        return "unknown"
    dirty = changed.returncode == 0 and changed.stdout.strip()
    return commit.stdout.strip() + (" with uncommitted changes" if dirty else "")


def utc_now() -> str:
    """The date and time a page names: ``YYYY-MM-DD HH:MM UTC``."""
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
