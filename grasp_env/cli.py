"""What the project's command-line tools share."""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

#: Most processes a command starts: beyond four a CPU they only wait and take memory.
MAX_WORKERS = 4 * (os.cpu_count() or 1)


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``--help`` with each option's default shown, except where there is none to show (a
    default of None, False or empty: the option's help says what happens without it); a
    default of 0 is shown."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        default = action.default
        if (
            default is None
            or default is False
            or default in ([], ())
            or default is argparse.SUPPRESS
        ):
            return action.help
        return super()._get_help_string(action)


def out_dir_problem(path: Path) -> str | None:
    """Why results cannot go to folder ``path`` (created if missing), or None if they can:
    checked before any work starts."""
    if path.exists() and not path.is_dir():
        return f"{path} exists and is not a directory"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"{path} cannot be created ({exc.strerror or exc})"
    if not os.access(path, os.W_OK | os.X_OK):
        return f"{path} is not writable"
    return None


def positive_int(text: str) -> int:
    """An ``argparse`` type: an integer > 0."""
    return _int_at_least(text, 1, "a positive integer")


def nonnegative_int(text: str) -> int:
    """An ``argparse`` type: an integer >= 0."""
    return _int_at_least(text, 0, "a non-negative integer")


def workers(text: str) -> int:
    """An ``argparse`` type: a number of processes, 1 to ``MAX_WORKERS``."""
    value = positive_int(text)
    if value > MAX_WORKERS:
        raise argparse.ArgumentTypeError(
            f"expected at most 4 x the CPUs = {MAX_WORKERS} processes, got {text!r}"
        )
    return value


def positive_float(text: str) -> float:
    """An ``argparse`` type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def _int_at_least(text: str, least: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value
