"""The paper's centred pre-liftoff placement (section 3.2), its fallback when no placement
tips the object: the palm centred over the object, parallel to the support, and the fingers
closed at equal rates until they touch (:func:`close_until_touch`, which the env's
``"preliftoff"`` start and the scripted policy use too).

Apart from the tipping placements of :mod:`grasp_env.planning.preliftoff` (which still
exports these names), because it needs neither the tippability regions nor the LPs.
"""

from __future__ import annotations

import math

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core.state import State
from grasp_env.planning.plan import touching_bodies
from grasp_env.simulator import Simulator

__all__ = [
    "PALM_CLEARANCE",
    "PRELIFTOFF_STEP",
    "centred_hand",
    "centred_placement",
    "close_until_touch",
]

#: Gap between the hanging tip of the longer finger and the support in the centred
#: pre-liftoff placement, in palm widths (the paper's "just high enough so that the longer
#: finger could not touch the support").
PALM_CLEARANCE = 0.01


#: Finger step of the pre-liftoff closing motion (rad); the first touch is then located
#: exactly from the simulator's events, so the step only changes the cost.
PRELIFTOFF_STEP = 0.1


def centred_hand(scene, object_vertices_W: np.ndarray | None = None) -> np.ndarray:
    """The paper's centred pre-liftoff hand: palm over the object's centroid, parallel to the
    support, ``PALM_CLEARANCE`` palm widths above the longer finger's reach of the support
    (higher if the object is taller), fingers hanging straight down.

    Args:
        scene: the scene (its hand and, unless given, its object).
        object_vertices_W: the object's vertices ``(n, 2)`` in the world; default the scene's.

    Returns:
        Hand configuration ``(x_p, y_p, theta_p, q1, q2)``, shape (5,).
    """
    v = scene.object.vertices_W0 if object_vertices_W is None else object_vertices_W
    reach = max(max(f.length for f in scene.fingers), float(v[:, 1].max()))
    q = np.clip(np.full(2, -0.5 * math.pi), scene.joint_limits[:, 0], scene.joint_limits[:, 1])
    x = float(geo.polygon_centroid(v)[0])
    return np.array([x, reach + PALM_CLEARANCE * scene.palm.width, 0.0, q[0], q[1]])


def centred_placement(sim: Simulator, step: float = PRELIFTOFF_STEP) -> State:
    """The paper's fallback pre-liftoff placement: the palm at :func:`centred_hand`, the
    fingers closed at equal rates until each touches the object (:func:`close_until_touch`)."""
    scene = sim.scene
    state = sim.settle(scene.object.start_pose.copy(), centred_hand(scene))
    return close_until_touch(sim, state, step)


def close_until_touch(sim: Simulator, state: State, step: float = PRELIFTOFF_STEP) -> State:
    """Close both fingers at equal rates until each has touched the object or they jam.

    The fingers move in steps of ``step`` rad; a finger that touches stops there (its first
    touch located exactly from the simulator's ``new_contact`` event) while the other closes
    on. Stops too when both fingers are at their closing limits or the hand is blocked.
    """
    lim = sim.scene.joint_limits
    closing = np.array([1.0, -1.0])  # finger 1 closes as q1 grows, finger 2 as q2 falls
    for _ in range(int(4 * math.pi / step) + 4):
        done = [f"finger{i + 1}" in touching_bodies(state) for i in range(2)]
        if all(done) or state.jammed or state.hand_blocked:
            break
        q = state.finger_angles
        target = q.copy()
        for i in range(2):
            if not done[i]:
                target[i] = np.clip(q[i] + closing[i] * step, lim[i, 0], lim[i, 1])
        if np.array_equal(target, q):
            break
        new = sim.move_hand(state, fingers=target)
        touch = [
            e.s
            for e in new.events
            if e.kind == "new_contact"
            and any(k.body in (geo.FINGER1, geo.FINGER2) for k in e.contacts)
        ]
        if touch and min(touch) < 1.0:
            new = sim.move_hand(state, fingers=q + min(touch) * (target - q))
        state = new
    return state
