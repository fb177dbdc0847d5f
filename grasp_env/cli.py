"""What the project's command-line tools share."""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from pathlib import Path

#: Most processes a command starts: beyond four a CPU they only wait and take memory.
MAX_WORKERS = 4 * (os.cpu_count() or 1)
#: Largest seed: numpy's legacy generators (and so stable-baselines3's seeding) take no larger.
MAX_SEED = 2**32 - 1


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


def out_dir_problem(path: Path, create: bool = True) -> str | None:
    """Why results cannot go to folder ``path``, or None if they can: checked before any
    work starts. A missing folder is created, or with ``create=False`` only checked to be
    creatable (for a folder written only when the work is done, which an interrupted run
    must not leave behind empty)."""
    if path.exists() and not path.is_dir():
        return f"{path} exists and is not a directory"
    if not create:
        return _folder_problem(path, path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"{path} cannot be created ({exc.strerror or exc})"
    if not os.access(path, os.W_OK | os.X_OK):
        return f"{path} is not writable"
    return None


def file_problem(path: Path, make_folder: bool = True) -> str | None:
    """Why a file cannot be written at ``path``, or None if it can: not a directory, in a
    writable folder, which may be missing where ``make_folder`` (then it must be creatable:
    under a writable directory, no regular file on the way). Creates nothing: checked before
    any work starts."""
    if path.is_dir():
        return f"{path} is a directory"
    if path.exists() and not os.access(path, os.W_OK):
        return f"{path} is not writable"
    if not make_folder and not path.parent.is_dir():
        what = "is not a directory" if path.parent.exists() else "does not exist"
        return f"{path}: its folder {path.parent} {what}"
    return _folder_problem(path, path.parent)


def _folder_problem(path: Path, folder: Path) -> str | None:
    """Why ``folder`` (for ``path``) cannot be made or written in: its nearest existing
    folder (itself where it exists) is not a writable directory. Creates nothing."""
    existing = next(p for p in (folder, *folder.parents) if p.exists())
    if not existing.is_dir():
        return f"{path}: {existing} is not a directory"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"{path}: {existing} is not writable"
    return None


def read_text(path: str | os.PathLike) -> str:
    """The text of file ``path``, read as UTF-8; a one-line ``ValueError`` naming the file
    where it cannot be read or is not UTF-8."""
    try:
        return Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{str(path)!r} is not UTF-8 text: {exc.reason}") from None
    except OSError as exc:
        raise ValueError(f"{str(path)!r}: cannot read it ({exc.strerror or exc})") from None


def out_file(text: str) -> Path:
    """An ``argparse`` type: where a file is to be written, its folder made when it is
    (:func:`file_problem`)."""
    path = Path(text)
    if problem := file_problem(path):
        raise argparse.ArgumentTypeError(problem)
    return path


def existing_file(text: str) -> Path:
    """An ``argparse`` type: the path of a file that exists."""
    return _existing(text, Path.is_file, "file")


def existing_dir(text: str) -> Path:
    """An ``argparse`` type: the path of a directory that exists."""
    return _existing(text, Path.is_dir, "directory")


def _existing(text: str, is_kind: Callable[[Path], bool], kind: str) -> Path:
    path = Path(text)
    if not is_kind(path):
        what = f"not a {kind}" if path.exists() else f"no such {kind}"
        raise argparse.ArgumentTypeError(f"{what}: {text!r}")
    return path


def seed_int(text: str) -> int:
    """An ``argparse`` type: a seed, an integer from 0 to ``MAX_SEED``."""
    value = _int_at_least(text, 0, "a seed >= 0")
    if value > MAX_SEED:
        raise argparse.ArgumentTypeError(f"expected a seed <= 2**32 - 1, got {text!r}")
    return value


def one_of(*names: str) -> Callable[[str], str]:
    """An ``argparse`` type: one of ``names`` (for a value of :func:`fields`, which takes no
    ``choices``)."""

    def check(text: str) -> str:
        if text not in names:
            raise argparse.ArgumentTypeError(f"expected one of {', '.join(names)}, got {text!r}")
        return text

    return check


def fields(*kinds: Callable[[str], object]) -> type[argparse.Action]:
    """An ``argparse`` action of an option taking one value per kind (``nargs=len(kinds)``,
    a ``metavar`` name per value), each converted by its kind as a ``type`` would be: a bad
    one is a usage error naming the option, the value's name and the value."""

    class Fields(argparse.Action):
        def __call__(self, parser, namespace, values, option_string=None):
            converted = []
            for kind, name, text in zip(kinds, self.metavar, values, strict=True):
                try:
                    converted.append(kind(text))
                except (argparse.ArgumentTypeError, ValueError) as exc:
                    raise argparse.ArgumentError(self, f"{name}: {exc}") from None
            setattr(namespace, self.dest, converted)

    return Fields


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


#: Longest wall-clock limit a command takes, in seconds (about 11 days): the alarm that
#: enforces it takes no more than the platform's time_t (about 9.2e9 s), and no run is meant
#: to take longer.
MAX_SECONDS = 1e6


def seconds(text: str) -> float:
    """An ``argparse`` type: a time limit in seconds, a number > 0 and at most
    ``MAX_SECONDS``."""
    value = positive_float(text)
    if value > MAX_SECONDS:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_SECONDS:g} s, got {text!r}")
    return value


def _int_at_least(text: str, least: int, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value
