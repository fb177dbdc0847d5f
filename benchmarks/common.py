"""Shared helpers of the benchmark suite: machine description, timing and markdown output."""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from importlib import metadata
from pathlib import Path

#: The committed results (``--out benchmarks/results`` updates them).
RESULTS = Path(__file__).resolve().parent / "results"
#: The repository root.
REPO = Path(__file__).resolve().parent.parent
#: Default output folder: commands never overwrite the shipped results unless asked.
OUT = REPO / "runs" / "benchmarks"


def parser(module: str, doc: str, page: str | None = None, quick: str | None = None):
    """A benchmark's command line (``python -m <module>``): its docstring's first paragraph,
    every default shown in ``--help``; ``--quick`` with help ``quick`` and ``--out`` (default
    ``runs/benchmarks/<page>``, checked as the arguments are read: a file that can be
    written, :func:`grasp_env.cli.out_file`) where given."""
    from grasp_env.cli import HelpFormatter, out_file

    ap = argparse.ArgumentParser(
        prog=f"python -m {module}",
        description=" ".join(doc.split("\n\n")[0].split()).replace("``", ""),
        formatter_class=HelpFormatter,
    )
    if quick is not None:
        ap.add_argument("--quick", action="store_true", help=quick)
    if page is not None:
        ap.add_argument("--out", type=out_file, default=OUT / page, help="the page (markdown)")
    return ap


def page_main(
    argv: Sequence[str] | None,
    run: Callable[..., object],
    page: str,
    quick: str,
    options: Sequence[tuple] = (),
) -> int:
    """The command of a page, ``python -m`` of ``run``'s module: :func:`parser` with its
    docstring, ``page`` and ``quick``, and an option ``--<name>`` a row ``(name, type, help)`` or
    ``(name, type, help, default)`` of ``options``; parse ``argv`` and call ``run(quick, out,
    <name>=<value>, ...)``; exit status 0."""
    module = sys.modules[run.__module__]  # "__main__" under python -m: its spec has the name
    name = getattr(module.__spec__, "name", run.__module__)
    ap = parser(name, module.__doc__ or "", page, quick)
    for option, kind, text, *default in options:
        ap.add_argument(
            f"--{option}", type=kind, help=text, default=default[0] if default else None
        )
    args = ap.parse_args(argv)
    run(args.quick, args.out, **{option: getattr(args, option) for option, *_ in options})
    return 0


def headless() -> None:
    """Keep pygame (imported by renderers) off any display or sound device."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")


def cpu_model() -> str:
    """The CPU model name from ``/proc/cpuinfo`` (or what ``platform`` knows)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "absent"


def git_commit() -> str:
    """Commit of the ``grasp_env`` being measured (``+dirty`` with local changes), or its path
    when it is imported from outside a git work tree (e.g. an exported commit)."""
    import grasp_env

    src = Path(grasp_env.__file__).resolve().parent.parent

    def git(*args: str) -> str:
        out = subprocess.run(["git", *args], cwd=src, capture_output=True, text=True, check=True)
        return out.stdout.strip()

    try:
        if Path(git("rev-parse", "--show-toplevel")).resolve() != src:
            return f"{src} (not a git work tree)"
        dirty = git("status", "--porcelain", "--", "grasp_env")
        return git("rev-parse", "--short", "HEAD") + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return f"{src} (not a git work tree)"


def machine_line() -> str:
    """One markdown line naming the machine, software versions, commit, time and load."""
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    versions = ", ".join(
        f"{name} {_version(name)}" for name in ("numpy", "scipy", "gymnasium", "box2d")
    )
    return (
        f"Machine: {cpu_model()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"{versions}; grasp_env at {git_commit()}; "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; load average {load}."
    )


def table(header: Sequence[str], rows: Sequence[Sequence[object]], align: str = "") -> list[str]:
    """A markdown table; ``align`` gives one of ``l``/``r`` per column (default: left, right...)."""
    align = align or "l" + "r" * (len(header) - 1)
    rule = {"l": ":---", "r": "---:", "c": ":---:"}
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(rule[a] for a in align) + " |"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def write(path: Path, title: str, body: Sequence[str]) -> Path:
    """Write a results page: title, machine line, then ``body`` lines."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join([f"# {title}", "", machine_line(), "", *body]) + "\n")
    print(f"wrote {path}")
    return path


def median_time(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    """Median wall time of ``repeat`` calls of ``fn`` (seconds) and the last call's result."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


class BudgetExceeded(Exception):
    """A benchmarked call ran past its time limit."""


@contextlib.contextmanager
def time_limit(seconds: float):
    """Raise :class:`BudgetExceeded` in the main thread if the block runs over ``seconds``."""

    def _alarm(signum, frame):
        raise BudgetExceeded(f"over {seconds:g} s")

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
