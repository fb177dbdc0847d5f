"""Do seeded episodes depend on the OpenBLAS kernel? The same episodes under several core types.

Some machines set ``OPENBLAS_CORETYPE`` / ``OPENBLAS_L2_SIZE`` (e.g. ``Haswell`` and ``512``
on an AMD EPYC), which switches OpenBLAS to other kernels: sums in another order, other last
bits. Results must not depend on that. Each core type runs in its own worker process, with
the variables set before Python starts (``unset``: both removed), and records what
``threadpoolctl`` says the loaded OpenBLAS libraries run. Every worker plays the same seeded
episodes (:mod:`benchmarks.episodes`: the ``default`` shape randomizer and the ``extreme``
stress shapes, all three starts, random palm-control actions, up to ``--steps`` steps) and
records at reset and after every step

* a bit-exact digest of the object pose, the hand and every contact's point, normal and force;
* the discrete outcome: the contact set as ``(body, kind, object_feature, hand_feature)``, the
  event kinds in order, ``jammed``, ``hand_blocked``, form closure, ``terminated``,
  ``truncated``, ``is_success`` and the kind of ``sim_error`` (if any).

Each core type is compared with ``unset``, episode by episode: bit-different (any digest or
the episode's length differs), a discrete-outcome difference (any outcome or the length
differs; the first such step is listed) and the largest object-pose difference.

Targets: no discrete-outcome difference on default shapes, at most 1 in 1000 episodes on
extreme shapes.

Usage: ``python -m benchmarks.blas_variation [--episodes N] [--quick] [--steps S]
[--core-types T ...] [--workers W] [--out DIR]`` from the repository root (200 episodes a
suite: about 3 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from benchmarks.blas_worker import BLAS_VARS, blas_libraries, play, worker
from benchmarks.common import OUT, REPO, headless, parser, table, write
from grasp_env.cli import fields, one_of, out_dir_problem, positive_int, seed_int, workers

#: The core types the command runs: OpenBLAS takes a name it does not know with only a
#: warning and runs the kernel it detects, so no other is accepted.
CORE_TYPES = ("unset", "Haswell", "Sandybridge", "Prescott")
BASELINE = "unset"
#: ``OPENBLAS_L2_SIZE`` set with every named core type (as the machines that set one do).
L2_SIZE = "512"
SUITES = ("default", "extreme")
#: Largest share of episodes with a discrete-outcome difference, per suite.
TARGETS = {"default": 0.0, "extreme": 1e-3}


# ---------------------------------------------------------------------------------------
# Driver
# ---------------------------------------------------------------------------------------


def blas_environ(core: str, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """``base`` (default ``os.environ``) with the core type set (and ``OPENBLAS_L2_SIZE``),
    or both removed for ``"unset"``."""
    env = {k: v for k, v in (os.environ if base is None else base).items() if k not in BLAS_VARS}
    if core != BASELINE:
        env.update(OPENBLAS_CORETYPE=core, OPENBLAS_L2_SIZE=L2_SIZE)
    return env


def spawn(core: str, suite: str, seeds: Sequence[int], steps: int) -> dict[str, Any]:
    """Run :func:`worker` in a fresh interpreter with core type ``core``; its record, or
    ``{"error": ...}`` when the process fails (e.g. a core type the CPU cannot run)."""
    import grasp_env

    # Start in the folder of the grasp_env being measured, so that the worker imports it too
    # (an exported commit first on PYTHONPATH); the benchmarks come from this repository.
    src = Path(grasp_env.__file__).resolve().parent.parent
    env = blas_environ(core)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "record.json"
        args = ["--worker", suite, "--seeds", *map(str, seeds), "--steps", str(steps)]
        proc = subprocess.run(
            [sys.executable, "-m", "benchmarks.blas_variation", *args, "--record", str(path)],
            cwd=src,
            env=env,
            capture_output=True,
            text=True,
        )
        if proc.returncode != 0 or not path.exists():
            tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            return {"error": f"exit code {proc.returncode}: {tail}"}
        rec = json.loads(path.read_text())
    rec["core"] = core
    return rec


def compare(base: list[dict], other: list[dict]) -> dict[str, Any]:
    """Episode-by-episode differences of ``other`` from ``base`` (same seeds)."""
    bit, discrete, pose_same, pose_all = 0, [], 0.0, 0.0
    for e0, e1 in zip(base, other, strict=True):
        assert e0["seed"] == e1["seed"], (e0["seed"], e1["seed"])
        s0, s1 = e0["steps"], e1["steps"]
        bit += len(s0) != len(s1) or any(a[0] != b[0] for a, b in zip(s0, s1, strict=False))
        first = next(
            (k for k, (a, b) in enumerate(zip(s0, s1, strict=False)) if a[2] != b[2]),
            None if len(s0) == len(s1) else min(len(s0), len(s1)),
        )
        dpose = max(
            (
                max(abs(x - y) for x, y in zip(a[1], b[1], strict=True))
                for a, b in zip(s0, s1, strict=False)
                if a[1] and b[1]  # no pose after an exception
            ),
            default=0.0,
        )
        pose_all = max(pose_all, dpose)
        if first is None:
            pose_same = max(pose_same, dpose)
        else:
            discrete.append(
                {"seed": e0["seed"], "start": e0["start"], "kind": e0["kind"], "step": first}
            )
    return {
        "episodes": len(base),
        "bit_different": bit,
        "discrete_different": len(discrete),
        "discrete": discrete,
        "max_pose_diff_same": pose_same,
        "max_pose_diff_all": pose_all,
    }


def run(
    out: Path = OUT,
    *,
    episodes: int = 200,
    steps: int = 100,
    core_types: Sequence[str] = CORE_TYPES,
    suites: Sequence[str] = SUITES,
    workers: int = 2,
) -> dict[str, Any]:
    """Run every suite under every core type, compare with ``unset`` and write
    ``out/blas_variation.md`` and ``.json``; returns the report."""
    cores = [BASELINE, *(c for c in core_types if c != BASELINE)]
    seeds = list(range(episodes))
    jobs = [(c, s) for s in suites for c in cores]
    t0 = time.perf_counter()
    print(f"blas_variation: {len(jobs)} worker processes, {episodes} episodes each ...", flush=True)
    with ThreadPoolExecutor(max(1, workers)) as ex:
        futures = {ex.submit(spawn, *job, seeds, steps): job for job in jobs}
        done = {}
        for k, fut in enumerate(as_completed(futures), 1):
            done[futures[fut]] = fut.result()
            print(f"  {k}/{len(jobs)}: {' '.join(futures[fut])}", flush=True)
        records = {job: done[job] for job in jobs}
    wall = time.perf_counter() - t0
    report: dict[str, Any] = {
        "episodes": episodes,
        "steps": steps,
        "core_types": cores,
        "parent_environ": {k: os.environ.get(k) for k in BLAS_VARS},
        "wall": wall,
        "workers": {},
        "suites": {},
    }
    for (core, suite), rec in records.items():
        report["workers"].setdefault(core, {})[suite] = {
            k: rec.get(k) for k in ("environ", "blas", "cpu", "error")
        }
        report["workers"][core][suite]["steps"] = sum(
            len(e["steps"]) - 1 for e in rec.get("episodes", [])
        )
    for suite in suites:
        base = records[(BASELINE, suite)]
        rows = report["suites"][suite] = {}
        for core in cores[1:]:
            rec = records[(core, suite)]
            if "error" in base or "error" in rec:
                rows[core] = {"error": rec.get("error") or base.get("error")}
            else:
                rows[core] = compare(base["episodes"], rec["episodes"])
    out.mkdir(parents=True, exist_ok=True)
    (out / "blas_variation.json").write_text(json.dumps(report, indent=1) + "\n")
    write(out / "blas_variation.md", "Episodes under OpenBLAS core types", page(report))
    return report


def _arch(worker: dict[str, Any]) -> str:
    if worker.get("error"):
        return f"failed: {worker['error']}"
    archs = sorted({str(lib["architecture"]) for lib in worker.get("blas") or []})
    return ", ".join(archs) or "no OpenBLAS loaded"


def page(report: dict[str, Any]) -> list[str]:
    """The markdown body of the report."""
    n, steps = report["episodes"], report["steps"]
    parent = ", ".join(f"{k}={v}" for k, v in report["parent_environ"].items() if v) or "unset"
    cores = " ".join(report["core_types"])
    suites = " ".join(report["suites"])
    lines = [
        f"Command: `python -m benchmarks.blas_variation --episodes {n} --steps {steps} "
        f"--core-types {cores} --suites {suites}` "
        f"({n} episodes a suite, up to {steps} random palm-control steps each, seeds "
        f"0..{n - 1}, starts scene / preliftoff / random by seed mod 3). This process: "
        f"{parent}; wall time {report['wall']:.0f} s.",
        "",
        "## Worker processes",
        "",
        "Each row is one process per suite, started with the variables of its core type "
        f"(`OPENBLAS_CORETYPE=<core>`, `OPENBLAS_L2_SIZE={L2_SIZE}`; `unset`: both removed). "
        "*architecture*: what `threadpoolctl` reports for the OpenBLAS libraries loaded "
        "(numpy's and scipy's).",
        "",
    ]
    rows = []
    for core, by_suite in report["workers"].items():
        for suite, w in by_suite.items():
            environ = ", ".join(f"{k}={v}" for k, v in (w.get("environ") or {}).items() if v)
            cpu = f"{w['cpu']:.0f}" if w.get("cpu") is not None else "-"
            rows.append([core, suite, environ or "unset", _arch(w), w["steps"], cpu])
    lines += table(
        ["core type", "suite", "environment", "architecture", "steps", "CPU s"], rows, "llllrr"
    )
    other = sorted(
        f"{core} runs {_arch(w)}"
        for core, by_suite in report["workers"].items()
        for w in by_suite.values()
        if core != BASELINE and not w.get("error") and _arch(w) != core
    )
    if other:
        lines += [
            "",
            "Core types OpenBLAS reports under another name: "
            + "; ".join(sorted(set(other)))
            + ".",
        ]
    lines += [
        "",
        "## Differences from `unset`",
        "",
        "*bit-different*: episodes where any step's digest (object pose, hand, contact "
        "points, normals and forces, bit for bit) or the length differs. *discrete*: episodes "
        "where the contact set, the events, jammed, hand_blocked, form closure, "
        "terminated/truncated, is_success or sim_error differ at some step (or the length). "
        "*max pose diff*: largest difference of an object pose component (x, y in palm "
        "widths, theta in rad) at the same step, over episodes with the same discrete "
        "outcomes / over all. *target*: discrete differences allowed.",
        "",
    ]
    rows, seeds = [], []
    for suite, by_core in report["suites"].items():
        target = TARGETS.get(suite, 0.0)
        for core, c in by_core.items():
            if "error" in c:
                rows.append([suite, core, "-", "-", "-", "-", "-", f"failed: {c['error']}"])
                continue
            ok = c["discrete_different"] <= target * c["episodes"]
            rows.append(
                [
                    suite,
                    core,
                    c["episodes"],
                    c["bit_different"],
                    c["discrete_different"],
                    f"{c['max_pose_diff_same']:.1e}",
                    f"{c['max_pose_diff_all']:.1e}",
                    f"{_target(target)}: {'met' if ok else 'not met'}",
                ]
            )
            if c["discrete"]:
                listed = ", ".join(
                    f"{d['seed']} ({d['start']}, {d['kind']}, step {d['step']})"
                    for d in c["discrete"]
                )
                seeds.append(f"- {suite}, {core}: {listed}")
    lines += table(
        [
            "suite",
            "core type",
            "episodes",
            "bit-different",
            "discrete",
            "max pose diff (same)",
            "max pose diff (all)",
            "target",
        ],
        rows,
        "llrrrrrl",
    )
    if seeds:
        lines += [
            "",
            "Episodes with a discrete-outcome difference: seed (start, shape kind, first "
            "step that differs). Print one step by step under each setting, e.g. "
            f"`OPENBLAS_CORETYPE=Haswell OPENBLAS_L2_SIZE={L2_SIZE} python -m "
            "benchmarks.blas_variation --replay extreme SEED` and the same without the "
            "variables.",
            "",
            *seeds,
        ]
    return lines


def _target(share: float) -> str:
    return "0" if share == 0 else f"<= 1 in {round(1 / share)}"


def replay(suite: str, seed: int, steps: int) -> None:
    """Print episode ``(suite, seed)`` step by step: digest, object pose and outcome."""
    headless()
    ep = play(suite, seed, steps)
    environ = ", ".join(f"{k}={os.environ.get(k, '<unset>')}" for k in BLAS_VARS)
    archs = ", ".join(f"{lib['library']} {lib['architecture']}" for lib in blas_libraries())
    print(f"{environ}; OpenBLAS: {archs}")
    print(f"{suite} seed {seed}: start {ep['start']}, shape {ep['kind']}")
    for k, (digest, pose, discrete) in enumerate(ep["steps"]):
        print(f"{k:3d} {digest} pose {[x.hex() for x in pose]} {discrete}")


def main(argv: list[str] | None = None) -> int:
    ap = parser("benchmarks.blas_variation", __doc__, quick="3 episodes a suite")
    ap.add_argument("--episodes", type=positive_int, default=200, help="episodes a suite")
    ap.add_argument("--steps", type=positive_int, default=100, help="steps an episode at most")
    ap.add_argument(
        "--core-types",
        nargs="+",
        choices=CORE_TYPES,
        default=list(CORE_TYPES),
        metavar="TYPE",
        help=f"OpenBLAS core types ({' '.join(CORE_TYPES)}); unset is always run",
    )
    ap.add_argument("--suites", nargs="+", choices=SUITES, default=list(SUITES))
    ap.add_argument("--workers", type=workers, default=2, help="processes at a time")
    ap.add_argument("--out", type=Path, default=OUT, help="results folder")
    ap.add_argument(
        "--replay",
        nargs=2,
        action=fields(one_of(*SUITES), seed_int),
        metavar=("SUITE", "SEED"),
        help="print one episode's steps in this process and stop",
    )
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--seeds", type=int, nargs="*", help=argparse.SUPPRESS)
    ap.add_argument("--record", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        rec = worker(args.worker, args.seeds or [], args.steps)
        args.record.write_text(json.dumps(rec))
        return 0
    if args.replay:
        replay(*args.replay, args.steps)
        return 0
    if problem := out_dir_problem(args.out):
        ap.error(f"--out {problem}")
    episodes = 3 if args.quick else args.episodes
    report = run(
        args.out,
        episodes=episodes,
        steps=args.steps,
        core_types=args.core_types,
        suites=args.suites,
        workers=args.workers,
    )
    print((args.out / "blas_variation.md").read_text())
    failed = any("error" in c for s in report["suites"].values() for c in s.values())
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
