"""Memory and start-up: peak RSS of env processes, ``import grasp_env`` and ``gymnasium.make``.

Every measurement runs in a fresh ``python`` subprocess (the same interpreter and
``PYTHONPATH``):

* start-up: wall time of ``import gymnasium`` alone, then of ``import grasp_env`` (which
  imports gymnasium, numpy and scipy), ``gymnasium.make("FrictionlessGrasp-v0")``, the first
  ``reset`` and the first ``step`` (where loading, or compiling, the simulator shows) with
  numba's cache where the package keeps it (``NUMBA_CACHE_DIR`` unset); median of
  ``repeat`` processes, CartPole-v1's ``make`` for comparison; then the same cold (a new
  empty ``NUMBA_CACHE_DIR``: everything compiles; one process, at most 600 s) and warm
  (that folder filled; median of 3 processes); not with ``--quick``;
* one env process: peak RSS (``VmHWM``, which ``exec`` resets, unlike ``ru_maxrss``) after
  the imports, after ``make`` and after ``steps`` random-action steps;
* eight workers: ``gymnasium.make_vec(..., vectorization_mode="async")`` with the ``fork``
  start method (and ``spawn`` unless quick); sum over the workers of their peak RSS
  (``VmHWM``) and of their proportional set size (PSS, shared pages split between
  processes) after ``steps`` vector steps, plus the parent's peak RSS;
* the import time of each heavy package under ``import grasp_env`` (``-X importtime``).

Usage: ``python -m benchmarks.memory [--quick]``
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.common import page_main, table, write

STARTUP = """
import json, time
t0 = time.perf_counter(); import gymnasium as gym; t1 = time.perf_counter()
out = {"import gymnasium": t1 - t0}
t0 = time.perf_counter(); gym.make("CartPole-v1")
out["make CartPole-v1"] = time.perf_counter() - t0
t0 = time.perf_counter(); import grasp_env; out["import grasp_env"] = time.perf_counter() - t0
t0 = time.perf_counter(); env = gym.make("FrictionlessGrasp-v0")
out["make FrictionlessGrasp-v0"] = time.perf_counter() - t0
t0 = time.perf_counter(); env.reset(seed=0); out["first reset"] = time.perf_counter() - t0
a = env.action_space.high
t0 = time.perf_counter(); env.step(a); out["first step (fingers close)"] = time.perf_counter() - t0
t0 = time.perf_counter(); env.step(a); out["second step"] = time.perf_counter() - t0
print(json.dumps(out))
"""

ONE_ENV = """
import json, sys
import numpy as np
def peak():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
out = {"python": peak()}
import gymnasium as gym, grasp_env
out["after imports"] = peak()
env = gym.make("FrictionlessGrasp-v0")
obs, _ = env.reset(seed=0)
out["after make + reset"] = peak()
steps = int(sys.argv[1])
actions = np.random.default_rng(0).uniform(-1, 1, (steps, 2)).astype(np.float32)
for a in actions:
    obs, r, term, trunc, _ = env.step(a)
    if term or trunc:
        env.reset()
out[f"after {steps} steps"] = peak()
print(json.dumps(out))
"""

WORKERS = """
import json, sys
import numpy as np
import gymnasium as gym, grasp_env
steps, n, context = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
def status(pid, field):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith(field):
            return int(line.split()[1]) / 1024
def pss(pid):
    for line in open(f"/proc/{pid}/smaps_rollup"):
        if line.startswith("Pss:"):
            return int(line.split()[1]) / 1024
envs = gym.make_vec("FrictionlessGrasp-v0", num_envs=n, vectorization_mode="async",
                    vector_kwargs={"context": context})
envs.reset(seed=0)
rng = np.random.default_rng(0)
for _ in range(steps):
    envs.step(rng.uniform(-1, 1, (n, 2)).astype(np.float32))
pids = [p.pid for p in envs.processes]
out = {
    "workers peak RSS sum": sum(status(p, "VmHWM:") for p in pids),
    "workers peak RSS max": max(status(p, "VmHWM:") for p in pids),
    "workers PSS sum": sum(pss(p) for p in pids),
    "parent peak RSS": status("self", "VmHWM:"),
}
envs.close()
print(json.dumps(out))
"""


#: Time limit of the cold start-up process, which compiles the whole simulator (1-3 minutes).
COLD_TIMEOUT = 600.0

#: Packages whose cumulative import time ``python -X importtime -c "import grasp_env"`` shows.
IMPORTS = ("grasp_env", "numpy", "scipy.optimize", "scipy.linalg", "gymnasium", "yaml", "pygame")


def import_breakdown() -> dict[str, float]:
    """Cumulative import seconds of :data:`IMPORTS` (nested: scipy.optimize is in grasp_env)."""
    proc = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", "import grasp_env"],
        capture_output=True,
        text=True,
        check=True,
    )
    out = {}
    for line in proc.stderr.splitlines():
        parts = line.split("|")
        if len(parts) == 3 and parts[2].strip() in IMPORTS:
            out[parts[2].strip()] = int(parts[1]) * 1e-6
    return out


def child(code: str, *args: object, timeout: float = 300.0, env: dict | None = None) -> dict:
    """Run ``code`` in a fresh interpreter; its last stdout line parsed as JSON."""
    proc = subprocess.run(
        [sys.executable, "-c", code, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=True,
        env=env,
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _median(runs: list[dict]) -> dict:
    """Median of each phase over start-up runs."""
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def package_cache(repeat: int) -> dict:
    """Start-up with numba's cache where the package keeps it (``NUMBA_CACHE_DIR`` unset: the
    ``__pycache__`` beside the simulator's sources), median of ``repeat`` processes."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    return _median([child(STARTUP, env=env) for _ in range(repeat)])


def compile_cache(warm: int) -> tuple[dict, dict] | str:
    """Start-up with numba's on-disk cache of the compiled simulator empty (cold: everything
    compiles) and then filled (warm: the median of ``warm`` processes), in a fresh
    ``NUMBA_CACHE_DIR``; or why there are none: the cold run went over :data:`COLD_TIMEOUT`,
    or left no cache files in the folder (numba ignored it: the run was not cold)."""
    with tempfile.TemporaryDirectory() as folder:
        env = dict(os.environ, NUMBA_CACHE_DIR=folder)
        try:
            cold = child(STARTUP, env=env, timeout=COLD_TIMEOUT)
        except subprocess.TimeoutExpired:
            return f"the cold run took over {COLD_TIMEOUT:g} s"
        if not any(Path(folder).rglob("*.nbi")):
            return "the cold run wrote no cache files to its `NUMBA_CACHE_DIR` (numba ignored it)"
        return cold, _median([child(STARTUP, env=env) for _ in range(warm)])


def _total(startup: dict) -> float:
    """import grasp_env + make + first reset + first step, seconds."""
    keys = ("import grasp_env", "make FrictionlessGrasp-v0", "first reset")
    return sum(startup[k] for k in keys) + startup["first step (fingers close)"]


def run(
    quick: bool,
    out: Path,
    steps: int | None = None,
    repeat: int | None = None,
    workers: int = 8,
    cold: bool | None = None,
) -> Path:
    """Run the memory and start-up benchmark and write its markdown page. ``cold``: also
    start up from an empty compile cache, where everything compiles (minutes; default: not
    with ``quick``)."""
    steps = steps if steps is not None else (20 if quick else 200)
    repeat = repeat if repeat is not None else (3 if quick else 7)
    cold = not quick if cold is None else cold
    print(f"memory: start-up with the package's cache, {repeat} processes ...", flush=True)
    startup = package_cache(repeat)
    print("start-up, package's cache (s):", startup)
    warm_runs = 1 if quick else 3
    if cold:
        print(
            "memory: start-up from an empty compile cache (everything compiles: a few "
            f"minutes), then {warm_runs} warm ...",
            flush=True,
        )
        cache = compile_cache(warm_runs)
        print("cold, warm (s):", cache)
    else:
        cache = "not measured (--quick: compiling everything takes minutes; run without it)"
    imports = import_breakdown()
    print(f"memory: one env process, {steps} steps ...", flush=True)
    one = child(ONE_ENV, steps)
    print("one env (MiB):", one)
    contexts = ("fork",) if quick else ("fork", "spawn")
    print(f"memory: {workers} env workers ({', '.join(contexts)}) ...", flush=True)
    vec = {ctx: child(WORKERS, steps, workers, ctx) for ctx in contexts}
    print("workers (MiB):", vec)
    columns = {"package's cache (ms)": startup}
    if isinstance(cache, tuple):
        columns["cold (ms)"], columns["warm (ms)"] = cache
        totals = (
            f"Import + make + reset + first step: cold **{_total(cache[0]):.1f} s**, warm "
            f"**{_total(cache[1]):.2f} s**, with the package's cache "
            f"**{_total(startup):.2f} s**."
        )
        warm, which = _total(cache[1]), "warm from the filled folder"
    else:
        totals = (
            f"No cold or warm numbers: {cache}. Import + make + reset + first step with the "
            f"package's cache: **{_total(startup):.2f} s**."
        )
        warm, which = _total(startup), "the package's cache"
    rows = [(k, *(f"{c[k] * 1e3:.1f}" for c in columns.values())) for k in startup]
    rows.append(
        (
            "**import grasp_env + make + reset + first step**",
            *(f"**{_total(c) * 1e3:.0f}**" for c in columns.values()),
        )
    )
    verdict = "met" if warm < 1.0 else "not met"
    body = [
        "## Start-up (fresh processes)",
        "",
        "The compiled simulator's machine code is cached on disk by numba. *Package's cache*: "
        "`NUMBA_CACHE_DIR` unset, so the `__pycache__` beside the simulator's sources "
        f"(median of {repeat}); *cold*: a new empty `NUMBA_CACHE_DIR`, so everything "
        "compiles (one process); *warm*: the same folder filled by the cold run (median of "
        f"{warm_runs}).",
        "",
        *table(["step", *columns], rows),
        "",
        totals,
        "",
        f"Target: warm start-up under 1 s: **{warm:.2f} s** ({which}), {verdict}.",
        "",
        'Cumulative import time by package (`python -X importtime -c "import grasp_env"`, '
        "one run; nested packages count inside their importers):",
        "",
        *table(["package", "time (ms)"], [(k, f"{v * 1e3:.0f}") for k, v in imports.items()]),
        "",
        f"## One env process: peak RSS (`VmHWM`), {steps} random-action steps",
        "",
        *table(["point", "peak RSS (MiB)"], [(k, f"{v:.1f}") for k, v in one.items()]),
        "",
        f"## {workers} parallel env workers (AsyncVectorEnv), {steps} vector steps",
        "",
        *table(
            ["start method", *next(iter(vec.values())).keys()],
            [(ctx, *(f"{v:.1f} MiB" for v in res.values())) for ctx, res in vec.items()],
        ),
        "",
        "RSS counts shared pages (the interpreter, numpy, scipy) in every process; PSS splits "
        "them, so the PSS sum is what the workers take from the machine.",
    ]
    return write(out, "Memory and start-up", body)


def main(argv: list[str] | None = None) -> int:
    quick = "20 steps, 3 start-up repeats, 1 warm run, fork only"
    return page_main(argv, run, "memory.md", quick)


if __name__ == "__main__":
    raise SystemExit(main())
