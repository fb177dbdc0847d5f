"""The paper's scripted planner: a command that plans and draws a grasp.

Command::

    python -m agents.scripted --scene fig13 --out DIR

plans a grasp with :func:`grasp_env.planning.plan_grasp` and writes into ``DIR``:
``filmstrip.png`` (frames like the paper's Fig. 13 at the steps where something happens:
hand, object, contacts with force arrows, a title per frame, a legend), ``grip_branches.png``
(``y*`` against the first finger's angle along every four-contact branch the grip
adjustment evaluated, zoomed to the adjustment, like Fig. 14), ``plan.gif`` (the whole
plan) and ``plan.json`` (per step: hand configuration, object pose, contacts, ``y*``, phase,
and the critical friction of each lifting motion, with the least of them:
:func:`agents.plan_report.lifting_friction`);
the images are drawn by :mod:`agents.plan_figures` and :mod:`agents.grip_branches`, the
plan's data and summary by :mod:`agents.plan_report`.
It prints a summary and exits with status 0 on form closure, 1 if the plan fails (the object
is tippable but no grasp was found; the summary says why, and a failed attempt that passed
through form closure without holding the object off the support is reported as such), 3 if
the object cannot be lifted without friction (both tippability regions empty), 2 on bad
arguments. ``--friction MU`` plays the plan against Coulomb friction ``MU`` at every contact:
where a lifting motion's critical friction is at most ``MU`` the hand jams there, and the
plan fails (status 1). Its exploratory lifting (up to ``EXPLORE_MOVES`` = 20,000 simulated
moves) logs its progress every 2,000 moves.

Step counts: the plan counts steps from its pre-liftoff placement (step 0, the fingers already
closed on the object), one step a planned increment; ``agents.evaluate`` counts
``FrictionlessGrasp-v0`` actions from the scene's start (fingers open), where closing the
fingers onto the object takes several actions and an increment larger than
``max_finger_step`` several more. On fig13 the plan reaches form closure at step 18 and the
env at step 27: 9 actions close the fingers (0.41 rad at most 0.05 rad an action), then the
18 lifting increments of 0.02 rad, one action each. The summary prints both. The images need
the ``viz`` extra (matplotlib, imageio).

The policy that plays the planner through the env, :class:`ScriptedPolicy`, is in
:mod:`agents.scripted_policy` (imported here, where users find it).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import shlex
import sys
from pathlib import Path

from agents.grip_branches import write_branch_plot
from agents.plan_figures import write_filmstrip, write_gif
from agents.plan_report import (
    friction_jam_step,
    friction_page,
    lifting_friction,
    plan_to_dict,
    summary,
)
from agents.provenance import git_commit, utc_now
from agents.scripted_policy import ScriptedPolicy
from grasp_env import planning
from grasp_env.cli import HelpFormatter, file_problem, out_dir_problem
from grasp_env.core.scene_loading import bundled_scenes, load_scene
from grasp_env.mechanics.friction import MU_MAX
from grasp_env.simulator import Simulator

__all__ = ["EXIT_FAILED", "EXIT_NOT_TIPPABLE", "EXIT_OK", "EXIT_USAGE", "ScriptedPolicy", "main"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_NOT_TIPPABLE = 0, 1, 2, 3


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m agents.scripted",
        description="Plan a frictionless enveloping grasp with the paper's three-phase planner "
        "and write a filmstrip, a Fig. 14-style branch plot, a GIF and the plan as JSON.",
        epilog=f"bundled scenes: {', '.join(bundled_scenes())}",
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "--scene", "--scenes", dest="scene", required=True, help="bundled scene name or YAML path"
    )
    parser.add_argument(
        "--out", type=Path, help="output directory (default: runs/scripted/<scene name>)"
    )
    parser.add_argument("--dq", type=float, default=0.02, help="finger increment of lifting (rad)")
    parser.add_argument(
        "--friction", type=float, default=0.0,
        help="Coulomb coefficient at every contact the plan is played against (0: none)",
    )  # fmt: skip
    parser.add_argument(
        "--friction-page", metavar="PATH",
        help="also write the lifting's critical friction as a page there "
        "(docs/friction_fig13.md is the shipped one for fig13)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    if not (math.isfinite(args.friction) and 0.0 <= args.friction <= MU_MAX):
        parser.error(f"--friction must be in [0, {MU_MAX:g}], got {args.friction!r}")
    if not (math.isfinite(args.dq) and 0 < args.dq <= 0.5):
        parser.error(f"--dq must be in (0, 0.5], got {args.dq!r}")
    if args.friction_page and (
        problem := file_problem(Path(args.friction_page), make_folder=False)
    ):
        parser.error(f"--friction-page {problem}")
    try:
        scene = load_scene(args.scene)
    except (ValueError, OSError) as exc:
        parser.error(f"--scene {args.scene!r}: {exc}")
    if args.out is None:
        args.out = Path("runs") / "scripted" / scene.name
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)
    print(f"planning {scene.name} ...", file=sys.stderr)
    if problem := out_dir_problem(args.out):
        parser.error(f"--out {problem}")

    sim = Simulator(scene)
    plan = planning.plan_grasp(scene, sim=sim, dq=args.dq)
    print(f"scene: {scene.name}")
    if plan.status == "not_tippable":
        print(f"not tippable: {plan.message}")
        return EXIT_NOT_TIPPABLE
    friction = lifting_friction(plan)
    with open(args.out / "plan.json", "w") as f:
        json.dump({"scene": scene.name, **plan_to_dict(plan, friction)}, f, indent=1)
    frames = write_filmstrip(plan, args.out / "filmstrip.png", friction)
    if args.friction_page:
        command = shlex.join(["python", "-m", "agents.scripted", *sys.argv[1:]])
        page = friction_page(plan, friction, command, utc_now(), git_commit())
        Path(args.friction_page).write_text(page)
        print(f"wrote {args.friction_page}")
    write_gif(plan, args.out / "plan.gif")
    written = ["plan.json", "filmstrip.png", "plan.gif"]
    if plan.success:
        write_branch_plot(sim, plan, args.out / "grip_branches.png")
        written.append("grip_branches.png")
    print(summary(plan, scene, friction))
    print(f"filmstrip frames (plan steps): {frames}")
    print(f"wrote {', '.join(written)} to {args.out}")
    if not plan.success:
        print(f"no grasp: {plan.message}")
        return EXIT_FAILED
    if args.friction > 0.0:
        jam = friction_jam_step(friction, args.friction)
        if jam is not None:
            print(f"no grasp with friction {args.friction:g}: the hand jams at step {jam} "
                  f"(critical friction {friction[jam]:.4g})")  # fmt: skip
            return EXIT_FAILED
        print(f"with friction {args.friction:g}: every lifting motion still moves the object")
    return EXIT_OK


if __name__ == "__main__":
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    sys.exit(main())
