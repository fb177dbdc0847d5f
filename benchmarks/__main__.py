"""Run the benchmark suite and write its pages (default ``runs/benchmarks/*.md``).

Usage: ``python -m benchmarks [--quick] [--only NAME ...] [--out DIR]``, from any directory
(full suite about 16 minutes, ``--quick`` about one: small budgets, no cold compile). ``--out
benchmarks/results`` updates the committed pages; by default nothing shipped is overwritten.
Names: throughput, work_precision, profile, memory, planner (the scripted planner on random
shapes, ``planner_shapes.py``), blas_variation (seeded episodes under several OpenBLAS core
types), step_times (the step-time tail on adversarial shapes), ppo (PPO training throughput,
``ppo_throughput.py``; left out of ``--quick`` unless named with ``--only``), scripted_speedup
(the scripted policy's episode rate against the simulator before its compiled core), step_parts
(the env's shell and the compiled move timed apart, unprofiled), batched (the batched env of
``gymnasium.make_vec`` against N and threads, resets, and where a batched step's time goes),
native (inside the compiled batched step, function by function: ``native_profile.py``, with
perf and gdb), bundled (the planner and the scripted policy on every bundled scene,
``bundled_scenes.py``; left out of ``--quick``), targets (last: every target the pages in the
output folder state, gathered on ``targets.md``)."""

from __future__ import annotations

import time
from pathlib import Path

from benchmarks import (
    batched,
    blas_variation,
    bundled_scenes,
    memory,
    native_profile,
    planner_shapes,
    ppo_throughput,
    profile_step,
    scripted_speedup,
    step_parts,
    step_times,
    targets,
    throughput,
    work_precision,
)
from benchmarks.blas_variation import CORE_TYPES
from benchmarks.common import OUT, headless, parser
from grasp_env.cli import out_dir_problem

SUITE = {
    "throughput": lambda quick, out: throughput.run(quick, out / "throughput.md"),
    "work_precision": lambda quick, out: work_precision.run(quick, out / "work_precision.md"),
    "profile": lambda quick, out: profile_step.run(quick, out / "profile.md"),
    "memory": lambda quick, out: memory.run(quick, out / "memory.md"),
    "planner": lambda quick, out: planner_shapes.run(
        out / "planner_shapes.md", shapes=2 if quick else 200, env=not quick
    ),
    "blas_variation": lambda quick, out: blas_variation.run(
        out, episodes=3 if quick else 200, core_types=QUICK_CORE_TYPES if quick else CORE_TYPES
    ),
    "step_times": lambda quick, out: step_times.run(out, episodes=3 if quick else 200),
    "ppo": lambda quick, out: ppo_throughput.run(quick, out / "ppo_throughput.md"),
    "step_parts": lambda quick, out: step_parts.run(quick, out / "step_parts.md"),
    "scripted_speedup": lambda quick, out: scripted_speedup.run(
        budget=3.0 if quick else 20.0, rounds=2 if quick else 3, out=out / "scripted_speedup.md"
    ),
    "batched": lambda quick, out: batched.run(quick, out / "batched.md"),
    "native": lambda quick, out: native_profile.run(quick, out / "native_profile.md"),
    "bundled": lambda quick, out: bundled_scenes.run(out / "bundled_scenes.md"),
    "targets": lambda quick, out: targets.run(out, out / targets.PAGE_NAME),
}
#: Left out of ``--quick`` unless named with ``--only``: ppo about 90 s even on its smallest
#: budget, bundled a minute or two (every bundled scene's whole plan and episodes).
QUICK_SKIP = ("ppo", "bundled")
#: OpenBLAS core types of ``--quick``'s blas_variation (the full suite runs all of them).
QUICK_CORE_TYPES = CORE_TYPES[:2]


def main(argv: list[str] | None = None) -> int:
    ap = parser("benchmarks", __doc__, quick="small budgets (about a minute)")
    ap.add_argument(
        "--only",
        nargs="+",
        choices=list(SUITE),
        metavar="PIECE",
        help=f"run only these pieces: {', '.join(SUITE)}",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=OUT,
        help="results folder (benchmarks/results: the committed one)",
    )
    args = ap.parse_args(argv)
    if problem := out_dir_problem(args.out):
        ap.error(f"--out {problem}")
    headless()
    names = args.only or [n for n in SUITE if not (args.quick and n in QUICK_SKIP)]
    start = time.perf_counter()
    for name in names:
        print(f"== {name} ...", flush=True)
        t0 = time.perf_counter()
        SUITE[name](args.quick, args.out)
        print(f"== {name}: {time.perf_counter() - t0:.0f} s")
    print(f"== suite: {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
