"""The scripted planner on every bundled scene: its plans, fig13's against the paper's Fig. 13,
and the scripted policy through the env from each start.

For each bundled scene: the whole plan (:func:`grasp_env.planning.plan_grasp`, in a process
that has already planned once, so the compiled simulator is loaded), its placement, phases,
form-closure step, final contacts, ``y*`` in object weights, the least critical friction of
its lifting and its CPU time, or why it failed. For fig13 (``--timeline``), every step's
phase, events, contacts and ``y*``, and the facts the paper reports for its Fig. 13 beside
ours. Then :class:`agents.scripted.ScriptedPolicy` through ``FrictionlessGrasp-v0`` on every
tippable scene from the ``"scene"`` and ``"preliftoff"`` starts, with ``palm_control`` False
and True: the env step of the first success (form closure off the support) and whether the
episode ends in it.

Usage: ``python -m benchmarks.bundled_scenes [--timeline SCENE] [--timeout T] [--workers W]
[--out FILE]``; ``--out benchmarks/results/bundled_scenes.md`` updates the shipped page.
"""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from benchmarks.common import BudgetExceeded, headless, parser, table, time_limit, write
from grasp_env.cli import seconds, workers

STARTS = ("scene", "preliftoff")
#: CPU seconds fig13's whole plan may take (the paper's VAX took 0.153 s).
FIG13_CPU_TARGET = 0.1
#: What the paper reports of its Fig. 13 run (section 4), beside which the page puts ours.
PAPER_FIG13 = {
    "steps": "15 frames",
    "liftoff": "during the first frames",
    "contact changes": "several three-contact force-closure grasps, a fourth contact forcing "
    "another to break (frames 3-5)",
    "constrained falls": "one (frames 2-4)",
    "form closure": "frame 11",
    "final grasp": "frame 14, five contacts",
    "final y*": "not given",
    "CPU time": "0.153 s on a VAX 11/750 (Fortran 77, IMSL)",
}


def _warm_up() -> None:
    """Plan fig13 once so that the measured plans do not pay for loading compiled code."""
    import grasp_env
    from grasp_env import planning

    headless()
    planning.plan_grasp(grasp_env.load_scene("fig13"))


def _contacts(state) -> str:
    return ", ".join(f"{c.body} {c.kind}" for c in state.contacts)


def plan_row(name: str, timeout: float, timeline: bool) -> dict:
    """Plan a grasp of bundled scene ``name``; its outcome (and every step with
    ``timeline``) as a dict."""
    import grasp_env
    from agents.plan_report import least_friction, lifting_friction
    from grasp_env import planning

    scene = grasp_env.load_scene(name)
    row = {"scene": name, "vertices": len(scene.object.vertices_B)}
    try:
        with time_limit(timeout):
            plan = planning.plan_grasp(scene)
    except BudgetExceeded:
        return {**row, "status": "timeout", "message": f"over {timeout:g} s", "cpu": timeout}
    weight = scene.object_weight
    final = plan.steps[-1] if plan.steps else None
    least = least_friction(lifting_friction(plan)) if plan.success else None
    row |= {
        "status": plan.status,
        "message": plan.message,
        "placement": plan.placement,
        "phases": plan.phase_bounds(),
        "form_closure": plan.form_closure_step() if plan.success else None,
        "final_contacts": _contacts(final.state) if plan.success else "",
        "grip": final.grip / weight if plan.success else None,
        "friction": least,
        "cpu": plan.cpu_time,
    }
    if timeline:
        fc = plan.form_closure_step()
        row["grip_at_closure"] = plan.steps[fc].grip / weight if fc is not None else None
        row["steps"] = [
            {
                "phase": st.phase,
                "note": st.note,
                "on_support": st.state.on_support,
                "contacts": _contacts(st.state),
                "n_contacts": len(st.state.contacts),
                "grip": st.grip / weight,
            }
            for st in plan.steps
        ]
    return row


def episode_row(name: str, start: str, palm_control: bool, timeout: float) -> dict:
    """One episode of the scripted policy on bundled scene ``name`` from ``start``."""
    import gymnasium as gym

    from agents.scripted_policy import ScriptedPolicy

    row = {"scene": name, "start": start, "palm_control": palm_control}
    env = gym.make("FrictionlessGrasp-v0", scene=name, start=start, palm_control=palm_control)
    t0 = time.process_time()
    first, steps, info = None, 0, {}
    try:
        with time_limit(timeout):
            obs, info = env.reset(seed=0)
            policy = ScriptedPolicy(env)
            policy.reset(obs, info)
            done = False
            while not done:
                obs, _, terminated, truncated, info = env.step(policy.act(obs))
                steps += 1
                if info["is_success"] and first is None:
                    first = steps
                done = terminated or truncated
    except BudgetExceeded:
        return {**row, "first": first, "steps": steps, "end": f"over {timeout:g} s"}
    finally:
        env.close()
    end = "success" if info.get("is_success") else info.get("sim_error") or "no grasp"
    return {
        **row,
        "first": first,
        "steps": steps,
        "end": end,
        "fallback": policy.on_fallback,
        "cpu": time.process_time() - t0,
    }


def _job(job: tuple) -> dict:
    kind, *args = job
    return (plan_row if kind == "plan" else episode_row)(*args)


def _span(a: int, b: int) -> str:
    return f"{a}" if a == b else f"{a}-{b}"


def _steps(bounds: dict, phase: str) -> str:
    return _span(*bounds[phase]) if phase in bounds else "-"


def _plans_table(plans: list[dict]) -> list[str]:
    rows = []
    for r in plans:
        ok = r["status"] == "form_closure"
        friction = r.get("friction")
        rows.append(
            [
                r["scene"],
                r["vertices"],
                r["status"],
                r.get("placement") or "-",
                _steps(r.get("phases", {}), "lifting") if ok else "-",
                _steps(r.get("phases", {}), "grip adjustment") if ok else "-",
                r["form_closure"] if ok else "-",
                r["final_contacts"] or "-",
                f"{r['grip']:.4f}" if ok else "-",
                f"{friction[1]:.4g} (step {friction[0]})" if friction else "-",
                f"{r['cpu']:.2f}",
            ]
        )
    header = [
        "scene",
        "vertices",
        "status",
        "pre-liftoff placement",
        "lifting steps",
        "grip-adjustment steps",
        "form closure (plan step)",
        "final contacts",
        "final y* (W)",
        "least critical friction",
        "CPU (s)",
    ]
    body = table(header, rows, align="lrllllrlrlr")
    failed = [r for r in plans if r["status"] != "form_closure"]
    if failed:
        body += ["", "Why the others have no plan:", ""]
        body += [f"- {r['scene']} ({r['status']}): {r['message']}" for r in failed]
    return body


def _targets(plans: list[dict]) -> list[str]:
    """The tippable scenes lifted, and fig13's plan time."""
    tippable = [r for r in plans if r["status"] != "not_tippable"]
    lifted = [r for r in tippable if r["status"] == "form_closure"]
    verdict = "met" if len(lifted) == len(tippable) else "not met"
    lines = [
        f"* target: every tippable bundled scene lifted: **{len(lifted)}/{len(tippable)}** "
        f"({verdict})"
    ]
    for r in plans:
        if r["scene"] == "fig13" and r["status"] == "form_closure":
            ok = "met" if r["cpu"] <= FIG13_CPU_TARGET else "not met"
            lines.append(
                f"* target: fig13 plan <= {FIG13_CPU_TARGET:g} s of CPU: **{r['cpu']:.3f} s** "
                f"({ok})"
            )
    return lines


def _fig13(row: dict) -> list[str]:
    """The timeline of ``row``'s plan and its facts beside the paper's Fig. 13."""
    steps = row["steps"]
    liftoff = next((i for i, s in enumerate(steps) if not s["on_support"]), None)
    changes = [
        i for i, s in enumerate(steps) if "new_contact" in s["note"] or "tip_to_edge" in s["note"]
    ]
    falls = [i for i, s in enumerate(steps) if "fall_start" in s["note"]]
    fc, final = row["form_closure"], steps[-1]
    bounds = row["phases"]
    ours = {
        "steps": f"{len(steps)} steps: "
        + ", ".join(f"{phase} {_span(a, b)}" for phase, (a, b) in bounds.items()),
        "liftoff": f"step {liftoff}" if liftoff is not None else "never",
        "contact changes": "at steps " + ", ".join(map(str, changes)) if changes else "none",
        "constrained falls": (f"{len(falls)}, at step " + ", ".join(map(str, falls)))
        if falls
        else "none",
        "form closure": f"step {fc}" if fc is not None else "never",
        "final grasp": f"step {len(steps) - 1}, {final['n_contacts']} contacts: "
        f"{final['contacts']}",
        "final y*": f"{row['grip']:.5f} object weights ({row['grip_at_closure']:.5f} at "
        "form closure)"
        if row["grip"] is not None
        else "-",
        "CPU time": f"{row['cpu']:.2f} s on one core of this machine",
    }
    body = [f"## {row['scene']} against the paper's Fig. 13", ""]
    body += table(["", "paper", "ours"], [[k, PAPER_FIG13[k], ours[k]] for k in PAPER_FIG13], "lll")
    body += ["", f"Every step of the {row['scene']} plan:", ""]
    body += table(
        ["step", "phase", "events", "on the support", "contacts", "y* (W)"],
        [
            [
                i,
                s["phase"],
                s["note"] or "-",
                "yes" if s["on_support"] else "no",
                s["contacts"],
                f"{s['grip']:.5f}" if s["grip"] == s["grip"] else "-",
            ]
            for i, s in enumerate(steps)
        ],
        align="rlllll",
    )
    return body


def _episodes_table(episodes: list[dict]) -> list[str]:
    rows = [
        [
            e["scene"],
            e["start"],
            "yes" if e["palm_control"] else "no",
            e["first"] if e["first"] is not None else "-",
            e["steps"],
            e["end"],
            ("re-placed or explored" if e.get("fallback") else "lifts from the env's hand")
            if e["first"] is not None
            else "-",
            f"{e['cpu']:.1f}" if "cpu" in e else "-",
        ]
        for e in episodes
    ]
    header = [
        "scene",
        "start",
        "palm_control",
        "first success (env step)",
        "episode steps",
        "episode end",
        "how",
        "CPU (s)",
    ]
    return table(header, rows, align="lllrrlll")


def report(plans: list[dict], episodes: list[dict], timeline: str, timeout: float) -> list[str]:
    """The page's body: the plans, the timeline scene against the paper, the episodes."""
    body = [
        "The planner (`grasp_env.planning.plan_grasp`) on every bundled scene, the whole plan "
        f"in a process that has planned once before (wall limit {timeout:g} s a plan or "
        "episode). Plan steps count from the pre-liftoff placement (step 0, fingers closed "
        "on the object); env steps count `FrictionlessGrasp-v0` actions from the scene's "
        "start (fingers open, at most `max_finger_step` a finger an action). `y*` in object "
        "weights W. Critical friction: the least Coulomb coefficient that can jam a lifting "
        "motion (docs/friction.md).",
        "",
    ]
    body += _plans_table(plans)
    body += ["", *_targets(plans)]
    timed = [r for r in plans if r["scene"] == timeline and "steps" in r]
    if timed and timed[0]["status"] == "form_closure":
        body += ["", *_fig13(timed[0])]
    body += [
        "",
        "## The scripted policy through the env",
        "",
        "`agents.scripted.ScriptedPolicy` on `FrictionlessGrasp-v0` (default time limit, "
        "`reset(seed=0)`), every tippable bundled scene, from the `scene` and `preliftoff` "
        "starts, with and without palm actions. First success: the first env step in form "
        "closure with the object off the support. How: whether the policy lifted from where "
        "the env put the hand, or re-placed the hand at the whole planner's placement or ran "
        "its exploratory lifting (palm actions only).",
        "",
    ]
    body += _episodes_table(episodes)
    return body


def run(out: Path, timeline: str = "fig13", timeout: float = 600.0, workers: int = 2) -> Path:
    """Plan every bundled scene and run the scripted policy on the tippable ones, ``workers``
    processes at a time; write the page."""
    import grasp_env
    from grasp_env.mechanics.tippability import tippability_regions

    names = grasp_env.bundled_scenes()
    tippable = [
        n
        for n in names
        if not all(r.is_empty for r in tippability_regions(grasp_env.load_scene(n)))
    ]
    jobs = [("plan", n, timeout, n == timeline) for n in names]
    jobs += [("env", n, s, pc, timeout) for n in tippable for s in STARTS for pc in (False, True)]
    with ProcessPoolExecutor(workers, initializer=_warm_up) as pool:
        results = list(pool.map(_job, jobs, chunksize=1))
    plans, episodes = results[: len(names)], results[len(names) :]
    return write(
        out, "Scripted planner on the bundled scenes", report(plans, episodes, timeline, timeout)
    )


def main(argv: list[str] | None = None) -> int:
    import grasp_env

    ap = parser("benchmarks.bundled_scenes", __doc__, "bundled_scenes.md")
    ap.add_argument(
        "--timeline", default="fig13", choices=grasp_env.bundled_scenes(),
        help="the scene whose plan is tabled step by step beside the paper's Fig. 13",
    )  # fmt: skip
    ap.add_argument("--timeout", type=seconds, default=600.0, help="wall seconds a plan or episode")
    ap.add_argument("--workers", type=workers, default=2, help="processes")
    args = ap.parse_args(argv)
    page = run(args.out, args.timeline, args.timeout, args.workers)
    print(page.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
