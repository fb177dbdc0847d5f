"""A pinch at a fold: two fingertips on opposite faces of the object, their lines of action
coinciding to tolerance, with a vertex on the support.

Closing the hand further there meets a fold of the contacts' equations: the force on the
support reaches zero, and just past that boundary the two fingertips are dependent to
tolerance, so they no longer hold the object to first order, while their curvature keeps it
from turning along their dependence (to second order the fingertips would cut into the
faces). The object can neither stay held nor fall there: the hand stops at the boundary,
where the contacts hold the object.

The states are the soak's (``python benchmarks/soak.py --seed 6 --only INDEX``): the state
before the failing step and the step's hand target. The oracle is the independent checker
(:func:`grasp_env.testing.check_state`).
"""

from __future__ import annotations

import numpy as np
import pytest

import grasp_env
from grasp_env import Simulator, testing
from grasp_env.errors import ComputationError

FINGERS_HANGING = [-0.5 * np.pi, -0.5 * np.pi]


def rectangle_scene(half_width: float, height: float, density: float) -> dict:
    """The soak's scene of an upright rectangle under the fig13 hand."""
    from grasp_env.envs.shapes import scene_to_dict

    d = scene_to_dict(grasp_env.load_scene("fig13"))
    d["palm"]["pose"] = [0.0, 0.71, 0.0]
    for f, angle in zip(d["fingers"], FINGERS_HANGING, strict=True):
        f["angle"] = angle
    v = [[-half_width, 0.0], [half_width, 0.0], [half_width, height], [-half_width, height]]
    d["name"] = "stress"
    d["object"] = {"vertices": v, "density": density}
    return d


#: (shape, step of soak seed 6): rectangle, start pose, start hand, target hand.
CASES = {
    # SimulationError before: "jam at s = 1e-10 with the object neither held nor falling"
    "49:608": (
        (0.21757808947488066, 0.1842379396325353, 0.009640505086109636),
        [0.015431081871484249, 0.11867366938703772, -0.12571910949146928],
        [
            -0.03330478501234451,
            0.7220724235598813,
            0.1077533683132569,
            -1.0903802386794939,
            -2.012697549753614,
        ],
        [
            -0.01873511505041519,
            0.7226297413308989,
            0.05916856437439123,
            -1.0501408837114228,
            -2.0520014783672766,
        ],
    ),
    # WorkLimitError before: the fall past the boundary crept on for 5000 pose solves
    "100:543": (
        (0.2919242259611433, 0.27481074663889343, 0.0027694177861058112),
        [-0.08997814345746598, 0.23872526977380998, -0.39299708974343484],
        [
            -0.03863772038041079,
            0.7925288655739532,
            -0.1714975994088154,
            -1.1477156229759415,
            -1.8368861863258803,
        ],
        [
            -0.04706181589184725,
            0.7890115197878586,
            -0.13827332966108133,
            -1.1290947206760606,
            -1.867537076199385,
        ],
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_pinch_at_a_fold_jams_where_the_contacts_hold_it(case: str) -> None:
    """The hand stops at the fold's boundary (no error, no 5000 pose solves), and the state
    it stops in is valid by the independent check: the support and both fingertips hold the
    object, with no admissible descent."""
    (half, height, density), pose, hand, target = CASES[case]
    scene = grasp_env.load_scene(rectangle_scene(half, height, density))
    sim = Simulator(scene)
    tol = 1e-9 * scene.palm.width
    start = sim.settle(np.array(pose), np.array(hand))
    np.testing.assert_array_equal(start.object_pose, pose)  # held where the soak had it
    chk = testing.check_state(scene, start.object_pose, start.hand, start.contacts, tol)
    assert not chk.violations, chk.violations
    try:
        state = sim.move_hand(start, palm=target[:3], fingers=target[3:])
    except ComputationError as exc:  # what the move raised before
        pytest.fail(f"{type(exc).__name__}: {exc}")
    assert state.jammed and state.events[-1].kind == "jam"
    assert sim.solves < sim.max_solves
    assert sorted(c.body for c in state.contacts) == ["finger1", "finger2", "support"]
    assert sorted(c.kind for c in state.contacts) == ["edge", "tip", "tip"]
    chk = testing.check_state(scene, state.object_pose, state.hand, state.contacts, tol)
    assert not chk.violations, chk.violations
    # the fingertips pinch the object: equal and opposite forces far above its weight
    tips = sorted(c.force for c in state.contacts if c.kind == "tip")
    assert tips[0] > 1e3 * scene.object_weight
    assert tips[1] - tips[0] <= 1e-6 * tips[1]
