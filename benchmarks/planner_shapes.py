"""How often the scripted planner lifts random convex shapes, and at what cost.

Each shape is the env's shape randomizer (``grasp_env.envs.shapes.random_shape_scene``) on
the fig13 hand, seeded ``seed, seed + 1, ...``. Every plan runs in its own process with a
wall-clock limit (a plan that tries every placement can take minutes), ``--workers`` at a
time. Writes a Markdown table (one row a shape, then the counts per outcome).

Usage: ``python -m benchmarks.planner_shapes [--seed S] [--shapes N] [--timeout T]
[--workers W] [--out FILE]`` from the repository root (12 shapes: about 5 minutes).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from benchmarks.common import OUT, table, write

ROOT = Path(__file__).resolve().parent.parent


def plan_one(seed: int) -> dict:
    """Plan a grasp of random shape ``seed``; the outcome as a JSON-able dict."""
    import numpy as np

    from grasp_env import planning
    from grasp_env.core.scene_loading import load_scene
    from grasp_env.envs.shapes import random_shape_scene
    from grasp_env.mechanics import closure as mech

    scene = random_shape_scene(np.random.default_rng(seed), load_scene("fig13"))
    plan = planning.plan_grasp(scene)
    final = plan.steps[-1].state if plan.steps else None
    ok = (
        plan.success
        and final is not None
        and "support" not in {c.body for c in final.contacts}
        and mech.is_form_closure(final)
        and bool(np.all(np.isfinite(final.object_pose)))
    )
    bounds = plan.phase_bounds()
    return {
        "seed": seed,
        "vertices": len(scene.object.vertices_B),
        "status": plan.status,
        "checked": bool(ok) if plan.success else None,
        "placement": plan.placement,
        "lifting_steps": (bounds["lifting"][1] - bounds["lifting"][0] + 1)
        if "lifting" in bounds
        else 0,
        "grip": plan.steps[-1].grip / scene.object_weight if plan.success else None,
        "cpu": plan.cpu_time,
    }


def _run(seed: int, timeout: float) -> dict:
    t0 = time.perf_counter()
    try:
        out = subprocess.run(
            [sys.executable, "-m", "benchmarks.planner_shapes", "--one", str(seed)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return {"seed": seed, "status": "timeout", "wall": timeout}
    if out.returncode != 0:
        tail = (out.stderr.strip().splitlines() or ["?"])[-1]
        return {"seed": seed, "status": "crash", "error": tail}
    res = json.loads(out.stdout.strip().splitlines()[-1])
    res["wall"] = time.perf_counter() - t0
    return res


def _fmt(x, spec: str) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def report(rows: list[dict], timeout: float) -> list[str]:
    """The page's body: the per-shape table and the counts per outcome."""
    counts = Counter(r["status"] for r in rows)
    body = [
        f"`python -m benchmarks.planner_shapes`: {len(rows)} shapes of the env's randomizer on "
        f"the fig13 hand, wall limit {timeout:.0f} s a plan. `checked`: the final state is in "
        "form closure with the object off the support (recomputed from the state).",
        "",
    ]
    body += table(
        [
            "seed",
            "vertices",
            "status",
            "checked",
            "placement",
            "lifting steps",
            "y* / W",
            "CPU (s)",
        ],
        [
            [
                r["seed"],
                r.get("vertices", "-"),
                r["status"],
                _fmt(r.get("checked"), ""),
                r.get("placement") or "-",
                r.get("lifting_steps", "-"),
                _fmt(r.get("grip"), ".3f"),
                _fmt(r.get("cpu"), ".1f"),
            ]
            for r in rows
        ],
        align="rrlllrrr",
    )
    body += ["", *table(["outcome", "shapes"], sorted(counts.items()))]
    return body


def run(
    out: Path,
    seed: int = 0,
    shapes: int = 12,
    timeout: float = 300.0,
    workers: int = 1,
) -> Path:
    """Plan ``shapes`` random shapes from ``seed`` on, ``workers`` at a time; write the page."""
    seeds = range(seed, seed + shapes)
    with ThreadPoolExecutor(workers) as pool:
        rows = list(pool.map(lambda s: _run(s, timeout), seeds))
    return write(out, "Scripted planner on random shapes", report(rows, timeout))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shapes", type=int, default=12)
    ap.add_argument("--timeout", type=float, default=300.0, help="wall seconds a plan")
    ap.add_argument(
        "--workers",
        type=int,
        default=1,
        help="plans at a time (CPU time is reported per plan: more workers share the cores)",
    )
    ap.add_argument("--out", type=Path, default=OUT / "planner_shapes.md")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)  # worker: plan one shape
    args = ap.parse_args(argv)
    if args.one is not None:
        print(json.dumps(plan_one(args.one)))
        return 0
    for name in ("shapes", "workers"):
        if getattr(args, name) < 1:
            ap.error(f"--{name} must be >= 1, got {getattr(args, name)}")
    if not args.timeout > 0:
        ap.error(f"--timeout must be > 0, got {args.timeout}")
    page = run(args.out, args.seed, args.shapes, args.timeout, args.workers)
    print(page.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
