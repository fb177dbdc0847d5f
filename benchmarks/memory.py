"""Memory and start-up: peak RSS of env processes, ``import grasp_env`` and ``gymnasium.make``.

Every measurement runs in a fresh ``python`` subprocess (the same interpreter and
``PYTHONPATH``):

* start-up: wall time of ``import gymnasium`` alone, then of ``import grasp_env`` (which
  imports gymnasium, numpy and scipy), ``gymnasium.make("FrictionlessGrasp-v0")``, the first
  ``reset`` and the first ``step`` (where loading, or compiling, the simulator shows);
  median of ``repeat`` processes, CartPole-v1's ``make`` for comparison; then the same
  cold (an empty ``NUMBA_CACHE_DIR``: everything compiles) and warm (that folder filled);
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

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.common import OUT, table, write

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


def compile_cache(warm: int) -> tuple[dict, dict, bool]:
    """Start-up with numba's on-disk cache of the compiled simulator empty (cold: everything
    compiles) and then filled (warm: the median of ``warm`` processes), in a fresh
    ``NUMBA_CACHE_DIR``; and whether the cold run wrote its cache there."""
    with tempfile.TemporaryDirectory() as folder:
        env = dict(os.environ, NUMBA_CACHE_DIR=folder)
        cold = child(STARTUP, env=env, timeout=900.0)
        written = any(Path(folder).rglob("*.nbi"))
        runs = [child(STARTUP, env=env) for _ in range(warm)]
    return cold, {k: statistics.median(r[k] for r in runs) for k in runs[0]}, written


def _total(startup: dict) -> float:
    """import grasp_env + make + first reset + first step, seconds."""
    keys = ("import grasp_env", "make FrictionlessGrasp-v0", "first reset")
    return sum(startup[k] for k in keys) + startup["first step (fingers close)"]


def run(
    quick: bool = False,
    out: Path = OUT / "memory.md",
    steps: int | None = None,
    repeat: int | None = None,
    workers: int = 8,
) -> Path:
    """Run the memory and start-up benchmark and write its markdown page."""
    steps = steps if steps is not None else (20 if quick else 200)
    repeat = repeat if repeat is not None else (3 if quick else 7)
    runs = [child(STARTUP) for _ in range(repeat)]
    startup = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    print("start-up (s):", startup)
    cold, warm, written = compile_cache(1 if quick else 3)
    print("cold (s):", cold, "warm (s):", warm)
    imports = import_breakdown()
    one = child(ONE_ENV, steps)
    print("one env (MiB):", one)
    contexts = ("fork",) if quick else ("fork", "spawn")
    vec = {ctx: child(WORKERS, steps, workers, ctx) for ctx in contexts}
    print("workers (MiB):", vec)
    phases = list(startup)
    rows = [
        (k, f"{startup[k] * 1e3:.1f}", f"{cold[k] * 1e3:.1f}", f"{warm[k] * 1e3:.1f}")
        for k in phases
    ]
    rows.append(
        (
            "**import grasp_env + make + reset + first step**",
            *(f"**{_total(x) * 1e3:.0f}**" for x in (startup, cold, warm)),
        )
    )
    verdict = "met" if _total(startup) < 1.0 and _total(warm) < 1.0 else "not met"
    body = [
        "## Start-up (fresh processes)",
        "",
        "The compiled simulator's machine code is cached on disk by numba. *Installed cache*: "
        f"the package's own cache (median of {repeat}); *cold*: an empty `NUMBA_CACHE_DIR`, "
        "so everything compiles (one process); *warm*: the same folder filled by the cold "
        f"run (median of {1 if quick else 3}).",
        "",
        *table(["step", "installed cache (ms)", "cold (ms)", "warm (ms)"], rows),
        "",
        f"Target: warm start-up under 1 s: {verdict}."
        + ("" if written else " (The cold run wrote no cache files: NUMBA_CACHE_DIR ignored?)"),
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
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="20 steps, 3 start-up repeats, fork only")
    ap.add_argument("--out", type=Path, default=OUT / "memory.md")
    args = ap.parse_args(argv)
    run(args.quick, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
