"""Training starts along the planner's lifts: the states its successful plans pass through,
for :class:`agents.wrappers.PlannerStarts` (a reverse curriculum, training only).

    python -m agents.planner_starts --out runs/planner_starts.pkl [--shapes 300] [--seed 0]
        [--approach | --scripted] [--workers 1]

The shapes are the lifting task's (``FrictionlessGraspLift-v0``'s random shapes, its reset
with seed ``--seed + k``; seeds that meet the held-out and validation episodes, 1,000,000 to
2,999,999, are refused). Each is planned from the scene's start
(:func:`grasp_env.planning.plan_grasp`, its exploratory search included); of a plan that
reaches form closure the states of its lifting phase are kept, in order, each as the hand
and the object pose a reset's options take (``palm``, ``fingers``, ``object_pose``).

With ``--approach`` a plan's states begin at the scene's start: the hand along the planner's
collision-free approach to its placement (:func:`grasp_env.planning.approach_path`, the path
the scripted policy drives), sampled at most one action's increment apart, the object at
rest; then the placement and the lift, for a curriculum that reaches back to where the
held-out episodes start. A shape the planner lifts but finds no approach to is left out.

With ``--scripted`` a shape's states are those of the scripted planner's episode in the
lifting task itself (:class:`agents.scripted_policy.ScriptedPolicy` from the env's start,
the planner's first placement, palm actions on), kept where the episode reaches a grasp:
its start and every state the env steps through up to the first grasp. Where lifting from the first
placement fails, the policy drives the hand to another placement or explores with palm
motion, so these states teach what the plans from the scene's start never show: leaving a
placement that does not lift.

With ``--select FILE --palm-travel D`` nothing is planned: the lifts of a starts file
whose palm travels more than ``D`` palm widths from where it starts are written (of the
scripted episodes, the shapes the planner lifts only by leaving its first placement), for a
file that :class:`agents.wrappers.PlannerStarts` weighs on its own.

The file is a pickle: a list of ``{"seed", "scene", "hands" (k, 5), "poses" (k, 3)}``, one
per lifted shape.
"""

from __future__ import annotations

import argparse
import math
import os
import pickle
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np

import grasp_env  # noqa: F401  (registers the env ids)
from agents.episodes import seed_problem
from agents.scripted_policy import ScriptedPolicy
from agents.wrappers import read_starts
from grasp_env.cli import out_file, seed_int, workers
from grasp_env.envs.checks import palm_problem, workspace_problem
from grasp_env.planning import approach_path, plan_grasp
from grasp_env.simulator import Simulator

#: The env whose shapes the starts are drawn on.
ENV_ID = "FrictionlessGraspLift-v0"
#: Largest hand change between two approach samples: palm translation (palm widths), palm
#: turn and finger angles (rad), the env's default largest action.
APPROACH_SPACING = (0.02, 0.05, 0.05)


def approach_hands(sim: Simulator, start, placement: np.ndarray) -> list[np.ndarray] | None:
    """Hands along the planner's approach from the state ``start`` (the scene's) to
    ``placement`` (the start included, the placement not), at most :data:`APPROACH_SPACING`
    apart; None where the planner finds no approach."""
    path = approach_path(sim, start, placement)
    if path is None:
        return None
    w = sim.scene.palm.width
    hands, a = [], start.hand
    for b in path:
        d = b - a
        n = max(
            1,
            math.ceil(np.abs(d[:2]).max() / (APPROACH_SPACING[0] * w)),
            math.ceil(abs(d[2]) / APPROACH_SPACING[1]),
            math.ceil(np.abs(d[3:]).max() / APPROACH_SPACING[2]),
        )
        hands += [a + (k / n) * d for k in range(n)]
        a = b
    return hands


def trajectory(scene, seed: int, approach: bool = False) -> dict | None:
    """The lifting states of the planner's plan for ``scene`` (None where it does not reach
    form closure, or with ``approach`` where it finds no approach): the states a reset can
    start from (palm and object centre in the palm workspace). With ``approach``, first the
    hands along the approach (:func:`approach_hands`) with the object at rest, then the
    placement."""
    plan = plan_grasp(scene)
    if not plan.success:
        return None
    phases = ("pre-liftoff", "lifting") if approach else ("lifting",)
    states = [step.state for step in plan.steps if step.phase in phases]
    hands = [s.hand for s in states]
    poses = [s.object_pose for s in states]
    if approach:
        sim = Simulator(scene)
        start = sim.reset()
        before = approach_hands(sim, start, states[0].hand)
        if before is None:
            return None
        hands = before + hands
        poses = [start.object_pose] * len(before) + poses
    return kept_states(scene, seed, hands, poses)


def kept_states(scene, seed: int, hands, poses) -> dict | None:
    """The states of ``hands``/``poses`` a reset can start from (palm and object centre in
    the palm workspace), as a starts-file entry; None where none is."""
    kept = [
        i
        for i, (hand, pose) in enumerate(zip(hands, poses, strict=True))
        if palm_problem(scene, hand[:3]) is None and workspace_problem(scene, *pose[:2]) is None
    ]
    if not kept:
        return None
    return {
        "seed": seed,
        "scene": scene,
        "hands": np.array(hands)[kept],
        "poses": np.array(poses)[kept],
    }


def scripted_episode(seed: int) -> dict | None:
    """The states of the scripted planner's episode in the lifting task reset with ``seed``
    (palm actions on), from the start to the first grasp (form closure off the support);
    None where the episode ends without one."""
    env = gym.make(ENV_ID, palm_control=True)
    obs, info = env.reset(seed=seed)
    policy = ScriptedPolicy(env)
    policy.reset(obs, info)
    base = env.unwrapped
    hands, poses = [base.state.hand.copy()], [base.state.object_pose.copy()]
    done = info["is_success"]
    while not done:
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        hands.append(base.state.hand.copy())
        poses.append(base.state.object_pose.copy())
        done = info["is_success"] or terminated or truncated
    scene = base.scene
    env.close()
    return kept_states(scene, seed, hands, poses) if info["is_success"] else None


def palm_travel(lift: dict) -> float:
    """How far, in palm widths, the palm of a starts-file lift gets from where it starts:
    the largest distance of its position from the first state's."""
    palm = lift["hands"][:, :2]
    return float(np.hypot(*(palm - palm[0]).T).max()) / lift["scene"].palm.width


def select(path, travel: float) -> list[dict]:
    """The lifts of the starts file ``path`` whose palm travels more than ``travel`` palm
    widths (:func:`palm_travel`); ValueError naming a bad file or distance."""
    if not (isinstance(travel, int | float) and math.isfinite(travel) and travel >= 0):
        raise ValueError(f"--palm-travel must be a finite distance >= 0, got {travel!r}")
    return [t for t in read_starts(path, "--select") if palm_travel(t) > travel]


def _planned(seed: int, approach: bool) -> dict | None:
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=seed)
    return trajectory(env.scene, seed, approach)


def collect(
    shapes: int, seed: int, approach: bool = False, scripted: bool = False, workers: int = 1
) -> list[dict]:
    """The trajectories of the lifting task's shapes on seeds ``seed`` to ``seed + shapes
    - 1`` (:func:`trajectory`, or with ``scripted`` :func:`scripted_episode`), in seed order,
    over ``workers`` processes; ValueError where a seed is reserved."""
    problem = seed_problem(seed, shapes) if shapes >= 1 else f"--shapes must be >= 1, got {shapes}"
    if problem:
        raise ValueError(problem)
    if approach and scripted:
        raise ValueError("--approach and --scripted exclude each other")
    one = scripted_episode if scripted else partial(_planned, approach=approach)
    seeds = range(seed, seed + shapes)
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            found = list(pool.map(one, seeds))
    else:
        found = [one(s) for s in seeds]
    return [t for t in found if t is not None]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m agents.planner_starts", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--out", type=out_file, required=True, help="the pickle to write")
    parser.add_argument("--shapes", type=int, default=300, help="shapes to plan")
    parser.add_argument("--seed", type=seed_int, default=0, help="the first shape's reset seed")
    parser.add_argument(
        "--approach",
        action="store_true",
        help="begin each plan's states at the scene's start, along the planner's approach",
    )
    parser.add_argument(
        "--scripted",
        action="store_true",
        help="the scripted planner's episodes in the lifting task from its own start instead",
    )
    parser.add_argument("--workers", type=workers, default=1, help="processes")
    parser.add_argument(
        "--select",
        metavar="FILE",
        help="plan nothing: write the lifts of this starts file that --palm-travel keeps",
    )
    parser.add_argument(
        "--palm-travel",
        type=float,
        metavar="D",
        help="with --select: keep the lifts whose palm travels more than D palm widths",
    )
    args = parser.parse_args(argv)
    if args.out.exists():
        parser.error(f"--out {str(args.out)!r} exists; remove it or name another file")
    if (args.select is None) != (args.palm_travel is None):
        parser.error("--select and --palm-travel go together")
    if args.select is not None and (args.approach or args.scripted):
        parser.error("--select plans nothing: it excludes --approach and --scripted")
    start = time.perf_counter()
    try:
        if args.select is not None:
            found = select(args.select, args.palm_travel)
        else:
            found = collect(args.shapes, args.seed, args.approach, args.scripted, args.workers)
    except ValueError as exc:
        parser.error(str(exc))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "wb") as f:
        pickle.dump(found, f)
    states = sum(len(t["poses"]) for t in found)
    what = f"of {args.select!r} kept" if args.select else f"of {args.shapes} shapes grasped"
    print(f"{len(found)} {what}, {states} states, {time.perf_counter() - start:.0f} s: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
