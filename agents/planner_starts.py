"""Training starts along the planner's lifts: the states its successful plans pass through,
for :class:`agents.wrappers.PlannerStarts` (a reverse curriculum, training only).

    python -m agents.planner_starts --out runs/planner_starts.pkl [--shapes 300] [--seed 0]

The shapes are the lifting task's (``FrictionlessGraspLift-v0``'s random shapes, its reset
with seed ``--seed + k``; seeds that meet the held-out and validation episodes, 1,000,000 to
2,999,999, are refused). Each is planned from the scene's start
(:func:`grasp_env.planning.plan_grasp`, its exploratory search included); of a plan that
reaches form closure the states of its lifting phase are kept, in order, each as the hand
and the object pose a reset's options take (``palm``, ``fingers``, ``object_pose``). The
file is a pickle: a list of ``{"seed", "scene", "hands" (k, 5), "poses" (k, 3)}``, one per
lifted shape.
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import time
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np

import grasp_env  # noqa: F401  (registers the env ids)
from agents.episodes import seed_problem
from grasp_env.envs.checks import palm_problem, workspace_problem
from grasp_env.planning import plan_grasp

#: The env whose shapes the starts are drawn on.
ENV_ID = "FrictionlessGraspLift-v0"


def trajectory(scene, seed: int) -> dict | None:
    """The lifting states of the planner's plan for ``scene`` (None where it does not reach
    form closure): the states a reset can start from (palm and object centre in the palm
    workspace)."""
    plan = plan_grasp(scene)
    if not plan.success:
        return None
    states = [
        step.state
        for step in plan.steps
        if step.phase == "lifting"
        and palm_problem(scene, step.state.hand[:3]) is None
        and workspace_problem(scene, *step.state.object_pose[:2]) is None
    ]
    if not states:
        return None
    return {
        "seed": seed,
        "scene": scene,
        "hands": np.array([s.hand for s in states]),
        "poses": np.array([s.object_pose for s in states]),
    }


def collect(shapes: int, seed: int) -> list[dict]:
    """The trajectories of the lifting task's shapes on seeds ``seed`` to ``seed + shapes
    - 1`` (:func:`trajectory`); ValueError where a seed is reserved."""
    problem = seed_problem(seed, shapes) if shapes >= 1 else f"--shapes must be >= 1, got {shapes}"
    if problem:
        raise ValueError(problem)
    env = gym.make(ENV_ID).unwrapped
    out = []
    for s in range(seed, seed + shapes):
        env.reset(seed=s)
        found = trajectory(env.scene, s)
        if found is not None:
            out.append(found)
    env.close()
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m agents.planner_starts", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--out", type=Path, required=True, help="the pickle to write")
    parser.add_argument("--shapes", type=int, default=300, help="shapes to plan")
    parser.add_argument("--seed", type=int, default=0, help="the first shape's reset seed")
    args = parser.parse_args(argv)
    if args.out.exists():
        parser.error(f"--out {str(args.out)!r} exists; remove it or name another file")
    start = time.perf_counter()
    try:
        found = collect(args.shapes, args.seed)
    except ValueError as exc:
        parser.error(str(exc))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "wb") as f:
        pickle.dump(found, f)
    states = sum(len(t["poses"]) for t in found)
    print(
        f"{len(found)} of {args.shapes} shapes lifted, {states} lifting states, "
        f"{time.perf_counter() - start:.0f} s: {args.out}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
