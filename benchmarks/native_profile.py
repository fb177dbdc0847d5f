"""Where the compiled batched step spends its time, function by function: a sampling profile
(Linux ``perf``) of random-action steps of a batched env on one thread, the compiled code's
addresses named by gdb (numba's JIT registers the code it loads with gdb's JIT interface).

cProfile (``benchmarks/profile_step.py``) sees one compiled call per step; this page looks
inside it. Samples are grouped by what the code does: numba's reference counts (atomic
``NRT_incref``/``NRT_decref`` wherever an array crosses a function boundary), allocation
(``malloc``/``free`` and numba's memory records, one per array a function makes), memory
copies, the math library, the project's compiled functions (by module), numba's own library
code, the Python interpreter (the step's Python part), the kernel, and compiled code gdb could
not name. Shares are of all samples of the process.

Needs ``perf`` allowed to sample another process (root, or ``kernel.perf_event_paranoid`` of 1
or less) and ``gdb``; where either is missing or refused the page says so and measures
nothing.

Usage: ``python -m benchmarks.native_profile [--quick] [--env ID] [--envs N] [--seconds S]``
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

from benchmarks.common import REPO, page_main, table, write

#: The env profiled by default, and its batch.
ENV_ID, ENVS = "FrictionlessGraspLift-v0", 64
#: Seconds of sampling (``--quick``: the smallest budget that still names the groups).
SECONDS, QUICK_SECONDS = 10.0, 1.0
#: perf's sampling rate (Hz).
FREQUENCY = 2000
#: Functions listed on the page.
TOP = 25

#: The child process: a batched env stepped with random actions until it is stopped; it
#: prints ``ready`` once warm (compiled code loaded, every kind of step taken).
CHILD = """
import sys
import numpy as np
from benchmarks.batched import make
env_id, n = sys.argv[1], int(sys.argv[2])
venv = make(env_id, n, threads=1, pool=256)
venv.reset(seed=0)
rng = np.random.default_rng(0)
space = venv.single_action_space
for k in range(10**9):
    venv.step(rng.uniform(space.low, space.high, (n, *space.shape)).astype(np.float32))
    if k == 200:
        print("ready", flush=True)
"""

#: Groups of native functions, the first whose rule matches a sample's ``(dso, name)`` wins.
REFCOUNT = "reference counts (NRT_incref, NRT_decref)"
ALLOCATION = "allocation (malloc, free, numba's memory records)"
COPIES = "memory copies (memcpy, memmove, memset)"
MATH = "math library (libm)"
NUMBA = "numba's runtime and library code (typed lists, sorting, the thread pool)"
PYTHON = "Python and numpy (the step's Python part, the random actions)"
KERNEL = "operating system kernel"
UNNAMED = "compiled code gdb could not name"
OTHER = "other"
_ALLOC_NAMES = re.compile(
    r"^(malloc|free|cfree|calloc|realloc|_int_malloc|_int_free|_int_realloc|__libc_\w+|"
    r"malloc_consolidate|unlink_chunk|tcache_\w+|PyMem_Raw\w+|NRT_MemInfo_\w+|NRT_dealloc|"
    r"NRT_Allocate\w*|NRT_Free|nrt_\w*alloc\w*|nrt_internal_\w+)(@.*|\.constprop.*)?$"
)


def group_of(dso: str, name: str) -> str:
    """The group of a sample in shared object ``dso`` at function ``name`` (named: a
    compiled function as :func:`function_name` gives it)."""
    if name in ("NRT_incref", "NRT_decref", "nrt_atomic_add", "nrt_atomic_sub"):
        return REFCOUNT
    if _ALLOC_NAMES.match(name):
        return ALLOCATION
    if re.match(r"^__(memcpy|memmove|memset)\w*", name) or name in ("memcpy", "memset"):
        return COPIES
    if dso.startswith("libm"):
        return MATH
    if name.startswith("grasp_env."):
        return "compiled: " + ".".join(name.split(".")[:3])
    if name.startswith(("numba.", "parallel region")) or dso.startswith(
        ("_helperlib.", "_nrt_python.", "omppool.", "workqueue.", "tbbpool.")
    ):
        return NUMBA
    if dso.startswith(("libpython", "python")) or re.match(r"^_\w+\.cpython-", dso):
        return PYTHON  # the interpreter, numpy's and numba's (dispatch) extension modules
    if dso == "[kernel.kallsyms]":
        return KERNEL
    if name.startswith("0x"):
        return UNNAMED
    return OTHER


def function_name(gdb_name: str) -> str:
    """A compiled function's dotted name from gdb's (``grasp_env::sim::pose::newton[abi:...]
    (Array<...>)`` or, where gdb leaves it mangled, ``_ZN9grasp_env3sim4pose6newtonB...``);
    a parallel region's gufunc as ``parallel region``; anything else as given."""
    if "__numba_parfor_gufunc" in gdb_name:
        return "parallel region"
    name = gdb_name
    for prefix in ("_ZN7cpython", "cpython::"):
        if name.startswith(prefix):
            name = name.replace(prefix, "_ZN" if prefix.startswith("_ZN") else "", 1)
    if name.startswith("_ZN"):
        parts, rest = [], name[3:]
        while rest and rest[0].isdigit():
            digits = re.match(r"\d+", rest).group()
            size = int(digits)
            parts.append(rest[len(digits) : len(digits) + size])
            rest = rest[len(digits) + size :]
        return ".".join(parts) if parts else name
    name = re.split(r"\[abi:|\(", name, maxsplit=1)[0]
    return name.replace("::", ".")


#: One line of ``perf report -n --sort dso,sym``: share, samples, shared object, kind, symbol.
_REPORT_LINE = re.compile(r"^\s*[\d.]+%\s+(\d+)\s+(.+?)\s+\[[.kgu]\]\s+(.+?)\s*$")


def parse_report(text: str) -> list[tuple[int, str, str]]:
    """``(samples, shared object, symbol)`` of each line of ``perf report --stdio -n
    --no-children --sort dso,sym`` (compiled code's symbol is its address). Shares are taken
    from the counts: perf's percentages, rounded to 0.01 line by line, add up to well over
    100 where thousands of addresses have a sample or two."""
    rows = []
    for line in text.splitlines():
        m = _REPORT_LINE.match(line)
        if m and not line.lstrip().startswith("#"):
            rows.append((int(m.group(1)), m.group(2), m.group(3)))
    return rows


def parse_symbols(text: str) -> list[str | None]:
    """gdb's answers to ``info symbol ADDR``, in order: the function's name, None where gdb
    names none."""
    names = []
    for line in text.splitlines():
        if line.startswith("No symbol matches"):
            names.append(None)
        elif " in section " in line:
            names.append(re.sub(r"( \+ \d+)? in section .*$", "", line))
    return names


def aggregate(rows: list[tuple[int, str, str]], names: dict[str, str | None]):
    """Shares of the samples by group and by function: ``(groups, functions)``, each a
    Counter of %; ``names`` maps compiled code's addresses to gdb's names."""
    groups, functions = Counter(), Counter()
    total = sum(samples for samples, _, _ in rows)
    for samples, dso, symbol in rows:
        share = 100.0 * samples / total
        name = symbol
        if symbol.startswith("0x"):
            gdb_name = names.get(symbol)
            name = function_name(gdb_name) if gdb_name else symbol
        dso = "" if dso.startswith("[JIT]") else dso
        group = group_of(dso, name)
        groups[group] += share
        functions[(name if group != UNNAMED else UNNAMED, group)] += share
    return groups, functions


def missing_tools() -> str | None:
    """Why the profile cannot be taken here, or None."""
    absent = [tool for tool in ("perf", "gdb") if shutil.which(tool) is None]
    if absent:
        return f"{' and '.join(absent)} not found"
    if not sys.platform.startswith("linux"):
        return "perf samples Linux processes only"
    return None


def sample(env_id: str, envs: int, seconds: float) -> tuple[str, dict[str, str | None]]:
    """perf's report of ``seconds`` of a child stepping the batched env, and gdb's names of
    the compiled addresses in it (asked while the child still runs)."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "PYTHONPATH": str(REPO)}
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, env_id, str(envs)], cwd=REPO, env=env,
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        if child.stdout.readline().strip() != "ready":
            raise RuntimeError(f"the profiled child exited with status {child.wait()}")
        with tempfile.TemporaryDirectory() as tmp:
            data = Path(tmp) / "perf.data"
            record = subprocess.run(
                ["perf", "record", "-q", "-F", str(FREQUENCY), "-p", str(child.pid), "-o",
                 str(data), "--", "sleep", str(seconds)],
                capture_output=True, text=True,
            )  # fmt: skip
            if record.returncode != 0 or not data.exists():
                raise RuntimeError(f"perf record failed: {record.stderr.strip()[-300:]}")
            report = subprocess.run(
                ["perf", "report", "-i", str(data), "--stdio", "-n", "--no-children",
                 "--sort", "dso,sym"],
                capture_output=True, text=True, check=True,
            ).stdout  # fmt: skip
            addresses = sorted({s for _, _, s in parse_report(report) if s.startswith("0x")})
            commands = Path(tmp) / "gdb.txt"
            commands.write_text("".join(f"info symbol {a}\n" for a in addresses))
            answer = subprocess.run(
                ["gdb", "-p", str(child.pid), "-batch", "-nx", "-x", str(commands)],
                capture_output=True, text=True,
            ).stdout  # fmt: skip
            named = parse_symbols(answer)
            if len(named) != len(addresses):
                raise RuntimeError(
                    f"gdb named {len(named)} of {len(addresses)} addresses (attaching to a "
                    "process may be refused here: kernel.yama.ptrace_scope)"
                )
            return report, dict(zip(addresses, named, strict=True))
    finally:
        child.kill()
        child.wait()


def run(quick: bool, out: Path, env: str = ENV_ID, envs: int = ENVS, seconds=None) -> Path:
    """Profile and write the page ``out``."""
    seconds = seconds or (QUICK_SECONDS if quick else SECONDS)
    command = (
        f"`python -m benchmarks.native_profile --env {env} --envs {envs} --seconds {seconds:g}`"
    )
    title = "Inside the compiled batched step"
    why = missing_tools()
    if why is None:
        try:
            report, names = sample(env, envs, seconds)
        except (RuntimeError, subprocess.CalledProcessError) as exc:
            why = str(exc)
    if why is not None:
        return write(out, title, [f"{command}: not measured here ({why})."])
    rows = parse_report(report)
    groups, functions = aggregate(rows, names)
    body = [
        f"{command}: {env} with {envs} envs on one thread, random actions, {seconds:g} s of "
        f"perf samples at {FREQUENCY} Hz: {sum(n for n, _, _ in rows):,} samples of the "
        "process, the shares below of them all.",
        "",
        "## By group",
        "",
        *table(["group", "share"], [[g, f"{p:.1f}%"] for g, p in groups.most_common()], "lr"),
        "",
        f"## The {TOP} costliest functions (own time)",
        "",
        *table(
            ["function", "group", "share"],
            [[f"`{f}`", g, f"{p:.2f}%"] for (f, g), p in functions.most_common(TOP)],
            "llr",
        ),
    ]
    return write(out, title, body)


def main(argv: list[str] | None = None) -> int:
    from grasp_env.cli import one_of, positive_int, seconds
    from grasp_env.envs import ENV_KWARGS

    return page_main(
        argv, run, "native_profile.md", f"{QUICK_SECONDS:g} s of samples",
        [("env", one_of(*ENV_KWARGS), "the env id", ENV_ID),
         ("envs", positive_int, "the batch", ENVS),
         ("seconds", seconds, f"seconds of samples (default {SECONDS:g})")],
    )  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(main())
