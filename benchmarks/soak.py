"""Soak test of ``FrictionlessGrasp-v0``: many random-action steps on many random shapes.

Every shape is a random convex polygon (3-12 vertices, diameter 5%-80% of the palm width,
aspect up to 1:30, density 1e-3..1e3, with nearly collinear vertices, very short edges, nearly
parallel edges, slivers, near-circles and a bulge on the resting edge mixed in:
:func:`benchmarks.soak_shapes.random_stress_scene`) in the hand set-up of the fig13 scene.
Each worker process runs its share of the shapes; on each shape an env with palm control
takes ``steps / shapes`` random actions (reset on termination), and after every step the returned
``info`` is checked by :func:`grasp_env.testing.check_state`, an independent re-computation
of the state's invariants (no penetration, contacts on both boundaries with ``|gap| <=
contact_tol``, non-negative forces, every touching pair listed, equilibrium and no admissible
descent), and the observation for NaN or infinity.

Exceptions, ``info["sim_error"]`` terminations and invariant violations are counted, and the
first few of each are written out with the seed and shape index that reproduce them.

Progress is appended to a JSON-lines checkpoint beside the report after every shape, so an
interrupted run resumes where it stopped (same ``--seed``, ``--steps``, ``--shapes``). The
report goes to ``runs/benchmarks/soak.md`` unless ``--out`` says otherwise
(``--out benchmarks/results/soak.md`` updates the committed page).

Usage::

    python -m benchmarks.soak --quick                      # ~2,000 steps, 20 shapes
    python -m benchmarks.soak --steps 20000 --shapes 100   # medium
    python -m benchmarks.soak                              # the full 1,000,000 x 1,000

(``python benchmarks/soak.py ...`` runs the same.)
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import platform
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.common import git_commit
from benchmarks.soak_shapes import POPULATION, SCENE_KINDS, random_stress_scene
from grasp_env.cli import HelpFormatter, nonnegative_int, out_file, positive_int, seed_int, workers
from grasp_env.testing import EQ_RTOL, check_state

#: The committed results (``--out benchmarks/results/soak.md`` updates them) and the default
#: output folder (the repository never overwrites shipped files unless asked).
RESULTS = Path(__file__).resolve().parent / "results"
OUT = Path(__file__).resolve().parents[1] / "runs" / "benchmarks"


# ---------------------------------------------------------------------------------------
# The soak
# ---------------------------------------------------------------------------------------


def random_action(rng: np.random.Generator, size: int = 5) -> np.ndarray:
    """A random action, biased to closing the fingers (``a0, a1`` uniform in ``[-0.4, 1]``,
    the palm's, with palm control, in ``[-1, 1]``) so that grasps, lifts and jams happen."""
    a = rng.uniform(-1.0, 1.0, 5)
    a[:2] = rng.uniform(-0.4, 1.0, 2)
    return a[:size].astype(np.float32)


def new_record(index: int) -> dict[str, Any]:
    """An empty record of a shape's steps (:func:`run_env` fills it)."""
    return {
        "index": index,
        "steps": 0,
        "episodes": 0,
        "exceptions": 0,
        "sim_errors": 0,
        "violating_steps": 0,
        "nan": 0,
        "penetration": -math.inf,
        "residual": 0.0,
        "gap": 0.0,
        "descent": 0.0,
        "wedged": 0,
        "examples": [],
        "time": 0.0,
    }


def soak_shape(seed: int, index: int, steps: int) -> dict[str, Any]:
    """Run ``steps`` random-action env steps on shape ``index``; return its record."""

    from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv

    rng = np.random.default_rng([seed, index])
    rec = new_record(index)
    t0 = time.perf_counter()
    try:
        d = random_stress_scene(rng)
        rec["kind"] = d["description"]
        start = str(rng.choice(["scene", "preliftoff", "random"]))
        env = FrictionlessGraspEnv(scene=d, palm_control=True, start=start)
    except Exception as exc:  # a valid random scene must always make an env
        rec["exceptions"] += 1
        rec["examples"].append(f"env construction: {exc!r}")
        rec["time"] = time.perf_counter() - t0
        return rec
    run_env(env, rng, steps, rec)
    rec["time"] = time.perf_counter() - t0
    return rec


def run_env(env, rng: np.random.Generator, steps: int, rec: dict[str, Any]) -> None:
    """``steps`` random-action steps of ``env`` (a reset with a seed from ``rng`` at the
    start, on every end and after 200 steps), every state checked by ``check_state`` and
    every observation against its space; the counts and worst figures go into ``rec``."""
    import gymnasium as gym

    tol = env.unwrapped.contact_tol * env.unwrapped.scenes[0].palm.width
    space: gym.spaces.Box = env.observation_space
    need_reset = True
    while rec["steps"] < steps:
        try:
            if need_reset:
                obs, info = env.reset(seed=int(rng.integers(2**31)))
                rec["episodes"] += 1
                need_reset, ep_steps = False, 0
            else:
                obs, _, term, trunc, info = env.step(random_action(rng, env.action_space.shape[0]))
                rec["steps"] += 1
                ep_steps += 1
                need_reset = term or trunc or ep_steps >= 200
        except Exception as exc:
            rec["exceptions"] += 1
            if len(rec["examples"]) < 3:
                rec["examples"].append(f"step {rec['steps']}: {exc!r}\n{traceback.format_exc()}")
            need_reset = True
            continue
        if "sim_error" in info:
            rec["sim_errors"] += 1
            if len(rec["examples"]) < 3:
                rec["examples"].append(f"step {rec['steps']}: sim_error {info['sim_error']}")
        state = env.state
        chk = check_state(
            state.scene, info["object_pose"], np.r_[info["palm_pose"], info["finger_angles"]],
            info["contacts"], tol,
        )  # fmt: skip
        if not np.all(np.isfinite(obs)) or not space.contains(obs):
            chk.violations.append(f"nan: observation outside its space: {obs.tolist()}")
        rec["penetration"] = max(rec["penetration"], chk.penetration)
        rec["gap"] = max(rec["gap"], chk.gap)
        if chk.wedged:  # held at second order: its first-order residual is a blocked descent
            rec["wedged"] += 1
        else:
            rec["residual"] = max(rec["residual"], chk.residual)
            rec["descent"] = min(rec["descent"], chk.descent)
        if chk.violations:
            rec["violating_steps"] += 1
            rec["nan"] += any(v.startswith("nan") for v in chk.violations)
            if len(rec["examples"]) < 3:
                rec["examples"].append(f"step {rec['steps']}: {chk.violations[:3]}")
    env.close()


def _work(job: tuple[int, int, int]) -> dict[str, Any]:
    return soak_shape(*job)


def checkpoint_path(seed: int, steps: int, shapes: int, folder: Path = OUT) -> Path:
    """The JSON-lines checkpoint of a soak, in ``folder``."""
    return folder / f"soak_pop{POPULATION}_{seed}_{steps}_{shapes}.jsonl"


def run_soak(
    steps: int, shapes: int, workers: int, seed: int, checkpoint: Path | None = None
) -> tuple[list[dict], float]:
    """Run (or resume) a soak; returns the per-shape records and the wall time of this call
    (a resumed soak times only the shapes it runs). Each record names the code it ran on
    (``"code"``, the commit when this call starts), so a soak resumed on other code says so."""
    code = git_commit()
    per_shape = [steps // shapes + (1 if i < steps % shapes else 0) for i in range(shapes)]
    done: dict[int, dict] = {}
    if checkpoint is not None and checkpoint.exists():
        for line in checkpoint.read_text().splitlines():
            if line.strip():
                rec = json.loads(line)
                done[rec["index"]] = rec
    jobs = [(seed, i, per_shape[i]) for i in range(shapes) if i not in done]
    t0 = time.perf_counter()
    if jobs:
        fh = checkpoint.open("a") if checkpoint is not None else None
        ctx = mp.get_context("spawn" if os.name == "nt" else "fork")
        try:
            for k, rec in enumerate(_results(jobs, workers, ctx)):
                rec["code"] = code
                done[rec["index"]] = rec
                if fh is not None:
                    fh.write(json.dumps(rec) + "\n")
                    fh.flush()
                if (k + 1) % max(1, len(jobs) // 20) == 0:
                    print(f"  {k + 1}/{len(jobs)} shapes, {time.perf_counter() - t0:.0f} s")
        except BrokenProcessPool:
            missing = sorted(j[1] for j in jobs if j[1] not in done)
            raise SystemExit(
                f"a soak worker died (a crash in native code) with shapes {missing} unfinished; "
                "re-run one with --only INDEX to find it"
            ) from None
        finally:
            if fh is not None:
                fh.close()
    return [done[i] for i in sorted(done)], time.perf_counter() - t0


def _results(jobs: list, workers: int, ctx):
    """Shape records as they finish: in worker processes (a worker that dies raises
    ``BrokenProcessPool`` instead of leaving the soak waiting forever), or serially."""
    if workers <= 1:
        yield from map(_work, jobs)
        return
    with ProcessPoolExecutor(workers, mp_context=ctx) as ex:
        for fut in as_completed([ex.submit(_work, job) for job in jobs]):
            yield fut.result()


def summarise(records: list[dict]) -> dict[str, Any]:
    keys = ("steps", "episodes", "exceptions", "sim_errors", "violating_steps", "nan")
    out: dict[str, Any] = {k: sum(r[k] for r in records) for k in keys}
    out["shapes"] = len(records)
    out["penetration"] = max(r["penetration"] for r in records)
    out["residual"] = max(r["residual"] for r in records)
    out["gap"] = max(r["gap"] for r in records)
    out["descent"] = min(r["descent"] for r in records)
    out["wedged"] = sum(r.get("wedged", 0) for r in records)
    out["cpu_time"] = sum(r["time"] for r in records)
    out["kinds"] = {k: sum(r.get("kind") == k for r in records) for k in SCENE_KINDS}
    out["bad_shapes"] = [
        r["index"] for r in records if r["exceptions"] or r["sim_errors"] or r["violating_steps"]
    ]
    return out


def _codes(records: list[dict]) -> str:
    """The commits the shapes ran on (the checkpoint's, for a resumed soak), with counts where
    more than one."""
    counts: dict[str, int] = {}
    for r in records:
        counts[r.get("code", "unrecorded")] = counts.get(r.get("code", "unrecorded"), 0) + 1
    if len(counts) == 1:
        return next(iter(counts))
    return ", ".join(f"{c} ({n} shapes)" for c, n in counts.items())


def write_report(path: Path, args: argparse.Namespace, s: dict, wall: float, records: list) -> None:
    rate = s["steps"] / s["cpu_time"] if s["cpu_time"] else math.nan
    kinds = ", ".join(f"{k} {v}" for k, v in s["kinds"].items())
    lines = [
        "# Soak test of FrictionlessGrasp-v0",
        "",
        f"Command: `python benchmarks/soak.py --steps {args.steps} --shapes {args.shapes} "
        f"--workers {args.workers} --seed {args.seed}`  ",
        f"Machine: {platform.machine()}, Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs; date {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; "
        f"code {_codes(records)}",
        "",
        "| figure | value |",
        "| --- | --- |",
        f"| env steps | {s['steps']} |",
        f"| random shapes | {s['shapes']} ({kinds}) |",
        f"| episodes | {s['episodes']} |",
        f"| exceptions raised | {s['exceptions']} |",
        f"| `info['sim_error']` terminations | {s['sim_errors']} |",
        f"| steps violating an invariant | {s['violating_steps']} |",
        f"| steps with NaN/inf | {s['nan']} |",
        f"| worst penetration (x palm width; tol 1e-9) | {s['penetration']:.2e} |",
        f"| worst listed-contact abs(gap) (x palm width) | {s['gap']:.2e} |",
        f"| worst equilibrium residual (x weight; limit {EQ_RTOL:g}) | {s['residual']:.2e} |",
        f"| most negative descent-LP optimum (x weight) | {s['descent']:.2e} |",
        f"| steps ending wedged (every descent blocked at second order; not in the two rows "
        f"above) | {s['wedged']} |",
        f"| env steps/s per process | {rate:.1f} |",
        f"| env steps/s, all workers (wall time of this run {wall:.0f} s) | "
        f"{s['steps'] / wall if wall > 1 else math.nan:.1f} |",
        "",
    ]
    if s["bad_shapes"]:
        lines += [
            f"Shapes with failures ({len(s['bad_shapes'])}); reproduce one with "
            f"`python benchmarks/soak.py --seed {args.seed} --only INDEX --steps N` "
            "where N is the shape's steps:",
            "",
        ]
        by_index = {r["index"]: r for r in records}
        for i in s["bad_shapes"]:
            r = by_index[i]
            lines.append(
                f"- shape {i} ({r.get('kind')}, {r['steps']} steps): exceptions "
                f"{r['exceptions']}, sim_errors {r['sim_errors']}, violating steps "
                f"{r['violating_steps']}"
            )
            for ex in r["examples"][:2]:
                lines.append(f"  - `{ex.splitlines()[0][:300]}`")
        lines.append("")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.soak",
        description=__doc__.splitlines()[0].replace("``", ""),
        formatter_class=HelpFormatter,
    )
    ap.add_argument("--steps", type=positive_int, default=1_000_000, help="total env steps")
    ap.add_argument("--shapes", type=positive_int, default=1000, help="random shapes")
    ap.add_argument(
        "--workers", type=workers, default=max(1, (os.cpu_count() or 2)), help="processes"
    )
    ap.add_argument("--seed", type=seed_int, default=0, help="seed of the shapes and actions")
    ap.add_argument("--quick", action="store_true", help="2,000 steps on 20 shapes")
    ap.add_argument(
        "--only", type=nonnegative_int, default=None, help="run one shape index (serial)"
    )
    ap.add_argument("--fresh", action="store_true", help="ignore an existing checkpoint")
    ap.add_argument(
        "--out",
        type=out_file,
        default=OUT / "soak.md",
        help="report page; the checkpoint goes beside it",
    )
    args = ap.parse_args(argv)
    if args.quick:
        args.steps, args.shapes = 2000, 20
    if args.only is not None:
        rec = soak_shape(args.seed, args.only, args.steps)
        print(json.dumps({k: v for k, v in rec.items() if k != "examples"}, indent=1))
        for ex in rec["examples"]:
            print(ex)
        return 0 if not (rec["exceptions"] or rec["sim_errors"] or rec["violating_steps"]) else 1
    if args.steps < args.shapes:
        ap.error(f"--steps {args.steps} must be >= --shapes {args.shapes}")
    ckpt = checkpoint_path(args.seed, args.steps, args.shapes, args.out.parent)
    if args.fresh and ckpt.exists():
        ckpt.unlink()
    ckpt.parent.mkdir(parents=True, exist_ok=True)
    print(f"soak: {args.steps} steps on {args.shapes} shapes, {args.workers} workers -> {ckpt}")
    records, wall = run_soak(args.steps, args.shapes, args.workers, args.seed, ckpt)
    s = summarise(records)
    write_report(args.out, args, s, wall, records)
    print(args.out.read_text())
    failed = s["exceptions"] or s["sim_errors"] or s["violating_steps"]
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
