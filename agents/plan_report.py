"""A grasp plan reported, for ``python -m agents.scripted``: the plan as JSON-ready data
(:func:`plan_to_dict`), where ``FrictionlessGrasp-v0`` from the scene's start reaches its
form closure (:func:`env_closure_step`: the env counts actions from the open hand, the plan
increments from its placement) and the summary the command prints (:func:`summary`)."""

from __future__ import annotations

import inspect
import itertools
import math

import numpy as np

from agents.provenance import generated_header
from grasp_env import planning
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.mechanics import closure as mech
from grasp_env.mechanics.friction import critical_friction


def lifting_friction(plan: planning.Plan) -> dict[int, float]:
    """The critical friction of every lifting motion, by the step it starts from: step ``k``
    (the state the lifting starts in, then each lifting step but the last) under the hand
    motion to step ``k + 1``, a lifting step (:func:`grasp_env.critical_friction`). The
    lifting survives Coulomb friction below the least of them."""
    out = {}
    for k in range(len(plan.steps) - 1):
        if plan.steps[k + 1].phase == "lifting":
            state = plan.steps[k].state
            out[k] = critical_friction(state, plan.steps[k + 1].state.hand - state.hand)
    return out


def least_friction(friction: dict[int, float]) -> tuple[int, float] | None:
    """The step and value of the least critical friction of :func:`lifting_friction` (the
    first step where it is attained), None without a lifting motion."""
    if not friction:
        return None
    step = min(friction, key=lambda k: (friction[k], k))
    return step, friction[step]


def friction_jam_step(friction: dict[int, float], mu: float) -> int | None:
    """The first step of :func:`lifting_friction` whose motion Coulomb friction ``mu`` can
    jam (critical friction at most ``mu``), None if the lifting survives it."""
    return next((k for k in sorted(friction) if friction[k] <= mu), None)


def pinch_friction(state) -> tuple[float, float, float] | None:
    """Nguyen's closed form for the state's two finger contacts, where there are exactly one
    on each finger: the angles (rad) between each contact normal and the line joining the
    contacts, and ``tan`` of the larger, the least friction at which the two can pinch the
    object (the forces along that line, inside both cones)."""
    fingers = [c for c in state.contacts if c.body in ("finger1", "finger2")]
    if sorted(c.body for c in fingers) != ["finger1", "finger2"]:
        return None
    a, b = fingers
    d = (b.point - a.point) / float(np.hypot(*(b.point - a.point)))
    angles = [
        math.acos(min(1.0, max(-1.0, float(n @ s)))) for n, s in ((a.normal, d), (b.normal, -d))
    ]
    return angles[0], angles[1], math.tan(max(angles)) if max(angles) < math.pi / 2 else math.inf


def friction_page(
    plan: planning.Plan, friction: dict[int, float], command: str, date: str, commit: str
) -> str:
    """A page of the plan's lifting against friction: each lifting motion's critical
    friction, the least, and at the state the lifting starts from the two finger contacts'
    closed form (:func:`pinch_friction`), with the date, the commit and the command."""
    scene = plan.steps[0].state.scene.name
    lines = [
        f"# `{scene}`: the lifting against friction",
        "",
        *generated_header("agents.scripted --friction-page", command, date, commit),
        "Each row is a lifting motion: the state at that step of the plan and the hand motion "
        "to the next step. `mu*` is the least Coulomb coefficient, the same at every contact, "
        "at which the contacts could hold the object at rest against that motion "
        "(`grasp_env.critical_friction`, [friction.md](friction.md)): below it the object "
        "moves as the frictionless plan says it may; at or above it the hand can jam.",
        "",
        "| step | phase | contacts | mu* |",
        "| --- | --- | --- | --- |",
    ]
    for k, mu in friction.items():
        st = plan.steps[k]
        bodies = ", ".join(f"{c.body} ({c.kind})" for c in st.state.contacts)
        lines.append(f"| {k} | {st.phase} | {bodies} | {mu:.4f} |")
    least = least_friction(friction)
    if least is not None:
        first = min(friction)
        lines += [
            "",
            f"Least: **{least[1]:.4f}** at step {least[0]}; at the state the lifting starts "
            f"from (step {first}): {friction[first]:.4f}.",
        ]
        pinch = pinch_friction(plan.steps[first].state)
        if pinch is not None:
            a1, a2, mu = pinch
            lines += [
                "",
                f"At step {first} the fingers pinch the object: the angles between the two "
                f"finger contacts' normals and the line joining them are "
                f"{math.degrees(a1):.2f} and {math.degrees(a2):.2f} degrees, and the tangent "
                f"of the larger, {mu:.4f}, is the least friction at which the two alone hold "
                "the object against the squeeze (Nguyen's condition); "
                + (
                    "it is the step's mu*: the other contacts offer no jam with less."
                    if math.isclose(mu, friction[first], rel_tol=1e-6)
                    else f"with the other contacts the step's mu* is {friction[first]:.4f}."
                ),
            ]
    return "\n".join(lines) + "\n"


def _json_friction(mu: float) -> float | str:
    return mu if math.isfinite(mu) else "inf"


def plan_to_dict(plan: planning.Plan, friction: dict[int, float] | None = None) -> dict:
    """The plan as JSON-ready data: status, phases and every step's state, with the critical
    friction of each lifting motion (``friction``, else :func:`lifting_friction`; ``"inf"``
    where no friction jams it, null on steps that start no lifting motion) and the least of
    them."""
    friction = lifting_friction(plan) if friction is None else friction
    least = least_friction(friction)
    steps = []
    for i, st in enumerate(plan.steps):
        s = st.state
        steps.append(
            {
                "index": i,
                "phase": st.phase,
                "note": st.note,
                "palm": s.palm_pose.tolist(),
                "fingers": s.finger_angles.tolist(),
                "object_pose": s.object_pose.tolist(),
                "contacts": [
                    {
                        "body": c.body,
                        "kind": c.kind,
                        "point": c.point.tolist(),
                        "normal": c.normal.tolist(),
                        "force": float(c.force),
                    }
                    for c in s.contacts
                ],
                "form_closure": bool(mech.is_form_closure(s)),
                "grip": st.grip if math.isfinite(st.grip) else None,
                "critical_friction": _json_friction(friction[i]) if i in friction else None,
            }
        )
    return {
        "status": plan.status,
        "message": plan.message,
        "placement": plan.placement,
        "cpu_time": plan.cpu_time,
        "phases": {k: list(v) for k, v in plan.phase_bounds().items()},
        "form_closure_step": plan.form_closure_step(),
        "min_critical_friction": None if least is None else _json_friction(least[1]),
        "min_critical_friction_step": None if least is None else least[0],
        "steps": steps,
    }


def env_actions(dh: np.ndarray, width: float, finger_step: float, palm_step) -> int:
    """How many ``FrictionlessGrasp-v0`` actions move the hand by ``dh`` (shape (5,)): equal
    actions, none beyond ``finger_step`` (rad) a finger or ``palm_step`` (palm widths, palm
    widths, rad) the palm."""
    scale = np.array(
        [width * palm_step[0], width * palm_step[1], palm_step[2], finger_step, finger_step]
    )
    return max(1, math.ceil(float(np.abs(np.asarray(dh) / scale).max()) - 1e-9))


def env_closure_step(plan: planning.Plan, scene) -> tuple[int, int] | None:
    """Where ``FrictionlessGrasp-v0`` from the scene's start, with the env's default step
    sizes, reaches the plan's form closure, as ``(actions to the plan's placement, env step
    of form closure)``; None without form closure or where the plan's palm is not the scene's
    (the env would first move the palm there: ``agents.scripted.ScriptedPolicy``).

    The plan counts its steps from its pre-liftoff placement (step 0: the fingers already
    closed on the object), one step a planned increment; the env starts from the scene's
    hand (fingers open) and counts actions, each moving a finger at most ``max_finger_step``:
    closing the fingers onto the object takes several actions, and so does an increment
    larger than one action."""
    fc = plan.form_closure_step()
    if fc is None or not np.allclose(plan.steps[0].state.hand[:3], scene.palm.pose):
        return None
    defaults = inspect.signature(FrictionlessGraspEnv.__init__).parameters
    finger, palm = defaults["max_finger_step"].default, defaults["max_palm_step"].default
    hands = [scene.initial_hand] + [st.state.hand for st in plan.steps[: fc + 1]]
    counts = [
        env_actions(np.subtract(b, a), scene.palm.width, finger, palm)
        for a, b in itertools.pairwise(hands)
    ]
    return counts[0], sum(counts)


def summary(plan: planning.Plan, scene=None, friction: dict[int, float] | None = None) -> str:
    """Phase boundaries, the form-closure step (and where the env from the scene's start
    reaches it, :func:`env_closure_step`), the least critical friction of the lifting
    (``friction``: :func:`lifting_friction`), the final contacts and y*, the CPU time."""
    lines = [f"status: {plan.status} ({plan.message})"]
    if plan.placement:
        lines.append(f"pre-liftoff placement: {plan.placement}")
    for phase, (a, b) in plan.phase_bounds().items():
        lines.append(f"  {phase:16s} steps {a:4d} .. {b:4d}")
    fc = plan.form_closure_step()
    if plan.success:
        lines.append(f"form closure at step: {fc} (plan steps from the pre-liftoff placement)")
        env = env_closure_step(plan, scene) if scene is not None else None
        if env is not None:
            lines.append(
                f"  in FrictionlessGrasp-v0 from the scene's start (agents.evaluate): env step "
                f"{env[1]}: {env[0]} actions close the fingers from the scene's open hand to "
                f"the placement, then {env[1] - env[0]} for the {fc} lifting increments (at "
                "most max_finger_step a finger an action)"
            )
    elif fc is not None:
        lines.append(
            f"form closure: none held; the failed attempt passed through form closure at step "
            f"{fc} without holding the object off the support"
        )
    else:
        lines.append("form closure: never")
    least = least_friction(friction or {})
    if least is not None:
        lines.append(
            f"least critical friction of the lifting: {least[1]:.4g} at step {least[0]} (a "
            "Coulomb coefficient at or above it can jam the lifting there; below it, every "
            "lifting motion moves the object)"
        )
    if plan.steps:
        final = plan.steps[-1]
        bodies = ", ".join(f"{c.body} ({c.kind})" for c in final.state.contacts)
        lines.append(f"final contacts: {len(final.state.contacts)}: {bodies}")
        weight = final.state.scene.object_weight
        if math.isfinite(final.grip):
            what = "final y*" if plan.success else "y* of the final state (not a grasp)"
            lines.append(f"{what}: {final.grip:.6g} ({final.grip / weight:.4f} object weights)")
    lines.append(f"CPU time: {plan.cpu_time:.2f} s")
    return "\n".join(lines)
