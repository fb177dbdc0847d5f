"""Pre-liftoff (the paper's section 3.2 with 2.4): hand placements from which squeezing
tips the object toward the palm: a fingertip at a support contact and the other finger in
the matching tippability region (Fig. 4), or the palm centred over the object and the
fingers closed until they touch (:mod:`~grasp_env.planning.centred`, whose names this
module exports too)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.state import State
from grasp_env.errors import ComputationError
from grasp_env.mechanics import closure as mech
from grasp_env.mechanics.tippability import TippabilityRegion, tippability_regions
from grasp_env.planning.centred import (
    PALM_CLEARANCE,
    PRELIFTOFF_STEP,
    centred_hand,
    centred_placement,
    close_until_touch,
)
from grasp_env.simulator import Simulator
from grasp_env.solvers.motion_lp import motion_lp

__all__ = [
    "PALM_ANGLES",
    "PALM_CLEARANCE",
    "PIVOT_HOLD_ANGLES",
    "PIVOT_PALM_ANGLES",
    "PIVOT_TRIES",
    "PRELIFTOFF_STEP",
    "TIP_CLEARANCE",
    "centred_hand",
    "centred_placement",
    "close_until_touch",
    "pivot_arm",
    "pivot_placements",
    "scoop_placement",
    "squeeze_tips",
    "tipping_placement",
]

#: Gap between a low fingertip and the support or the object, in palm widths
#: (:func:`scoop_placement`).
TIP_CLEARANCE = 1e-3

#: Palm angles (rad) of the tipping placements, in the order lifting tries them: the paper's
#: palm parallel to the support first, then tilted ever more (a tilted palm reaches further
#: under objects with parallel or undercut sides).
PALM_ANGLES = (0.0, -0.2, 0.2, -0.4, 0.4, -0.6, 0.6)

#: The dense grid of :func:`pivot_placements`, tried when lifting from every placement of
#: the sparse one (``PALM_ANGLES``, 24 holding-finger angles) gets stuck: palm angles (rad)
#: and holding-finger angles across its joint range.
PIVOT_PALM_ANGLES = tuple(round(0.1 * k, 1) for k in range(-10, 11))
PIVOT_HOLD_ANGLES = 96

#: Placements of the dense grid lifting tries, at most (the best ranked).
PIVOT_TRIES = 8


def _first_touch(
    scene,
    h: np.ndarray,
    finger: int,
    q_obj: np.ndarray,
    support: np.ndarray | None = None,
    start: float | None = None,
) -> float | None:
    """Angle at which finger ``finger`` (1 or 2), closing from ``start`` (default its open
    limit) with the rest of the hand fixed, first touches the object; None if it overlaps the
    object at the start, never touches it within its limits, or meets the polygon ``support``
    (if given; else the support is ignored) first."""
    lo_lim, hi_lim = scene.fingers[finger - 1].limits
    # finger 1 closes as q1 increases (counter-clockwise), finger 2 as q2 decreases
    q_open, q_shut = (lo_lim, hi_lim) if finger == 1 else (hi_lim, lo_lim)
    closing = 1.0 if finger == 1 else -1.0
    h = h.copy()
    h[2 + finger] = q_open if start is None else start
    link = kin.hand_polygons_W(scene, h)[finger]
    obj = geo.transform(q_obj, scene.object.vertices_B)
    if geo.penetration_depth(link, obj) > 0.0:
        return None
    joint = kin.body_poses_W(scene, h)[finger, :2]
    turn = geo.turn_to_contact(link, joint, obj, ccw=finger == 1)
    if turn > closing * (q_shut - h[2 + finger]):
        return None
    if support is not None and geo.turn_to_contact(link, joint, support, ccw=finger == 1) < turn:
        return None
    return h[2 + finger] + closing * turn


class _Candidate(NamedTuple):
    """A Fig. 4 placement of the search grid (:func:`_tipping_candidates`)."""

    state: State
    side: str
    region: TippabilityRegion  # the side's tippability region
    palm_angle: float
    arm: float  # moment arm of the pushing contact about the region's support contact


def _tipping_candidates(sim: Simulator, palm_angles, n_q: int, sides):
    """The Fig. 4 placements of a grid of palm angles and ``n_q`` holding-finger angles:
    for each tippability region in ``sides`` (right: finger 2's tip at the right support
    contact, finger 1 in the right region; left: the mirror), each palm angle and each angle
    of the holding finger, the holding fingertip is put on the support contact (slid up the
    object's side where the finger's body would enter the support), the other finger closes
    until it touches, and the placement is kept if that contact lies in the region, the hand
    is clear of the support and the object, and the joints are within limits."""
    scene = sim.scene
    q_obj = scene.object.start_pose.copy()
    left, right = tippability_regions(scene)
    tol = sim.tol
    for side, region in (("right", right), ("left", left)):
        if region.is_empty or side not in sides:
            continue
        hold = 2 if side == "right" else 1  # finger whose tip sits on the support contact
        move = 3 - hold
        p_C = region.contact_W
        side_up = _side_direction(scene, p_C, hold)
        lim = scene.fingers[hold - 1].limits
        for th in palm_angles:
            for q_hold in np.linspace(lim[0], lim[1], n_q)[1:-1]:
                u = np.array([math.cos(th + q_hold), math.sin(th + q_hold)])
                J = p_C - scene.fingers[hold - 1].length * u
                jx = scene.palm.width / 2 if hold == 2 else -scene.palm.width / 2
                o = J - geo.rotate(np.array([jx, 0.0]), th)
                h = np.array([o[0], o[1], th, -math.pi / 2, -math.pi / 2])
                h[2 + hold] = q_hold
                h[2 + move] = scene.fingers[move - 1].limits[0 if move == 1 else 1]
                # The finger's body pokes below its tip: slide the hand up the object's side.
                low = min(p[:, 1].min() for p in kin.hand_polygons_W(scene, h))
                if low < 0.0:
                    h[:2] += (-low + tol) / side_up[1] * side_up
                q_move = _first_touch(scene, h, move, q_obj)
                if q_move is None:
                    continue
                h[2 + move] = q_move
                if kin.hand_placement_problem(scene, q_obj, h, tol) is not None:
                    continue
                try:
                    state = sim.settle(q_obj, h)
                except ComputationError:
                    continue
                if np.abs(state.object_pose - q_obj).max() > 1e-9 * sim.size:
                    continue
                finger = f"finger{move}"
                touch = [c for c in state.contacts if c.body == finger]
                if not touch or not all(region.contains(c.point, c.normal, 1e-7) for c in touch):
                    continue
                arm = max(abs(float(geo.cross2(c.point - p_C, c.normal))) for c in touch)
                yield _Candidate(state, side, region, float(th), arm)


def tipping_placement(
    sim: Simulator, palm_angles=(0.0,), n_q: int = 24, sides=("right", "left")
) -> tuple[State, str] | None:
    """Pre-liftoff search for the paper's Fig. 4 placement (:func:`_tipping_candidates`).

    Among the valid placements the one whose contact has the largest moment arm about the
    support contact (the easiest to tip) is returned, with the side; None if there is none.
    ``sides`` restricts the search to some regions.
    """
    best = max(_tipping_candidates(sim, palm_angles, n_q, sides), key=lambda c: c.arm, default=None)
    return None if best is None else (best.state, best.side)


def pivot_placements(
    sim: Simulator,
    palm_angles=PIVOT_PALM_ANGLES,
    n_q: int = PIVOT_HOLD_ANGLES,
    limit: int = PIVOT_TRIES,
) -> list[tuple[State, str, float]]:
    """The Fig. 4 placements of a dense grid that tip the object about the pivot their
    holding finger actually makes (:func:`pivot_arm`), best first: at most ``limit``, each
    with its side and palm angle.

    Where the holding fingertip cannot reach the support contact (its body would enter the
    support, so it sits higher up the object's side), which pushing contacts tip the object
    depends on where that contact lies, not only on the paper's regions; the ranking favours
    the placements the paper's criterion, applied to the real holding contact, says tip the
    object most readily."""
    scored = [
        (arm, c)
        for c in _tipping_candidates(sim, palm_angles, n_q, ("right", "left"))
        if (arm := pivot_arm(c.state, c.region, 2 if c.side == "right" else 1)) > 0.0
    ]
    scored.sort(key=lambda ac: -ac[0])
    return [(c.state, c.side, c.palm_angle) for _, c in scored[:limit]]


def pivot_arm(state: State, region: TippabilityRegion, hold: int) -> float:
    """Moment arm, in the sense that tips the object, of the pushing finger's contact forces
    about the pivot of the holding finger ``hold`` (finger 2 for the right region).

    With the far support contact broken, the object is held by the region's support contact
    (a vertical normal) and the holding finger's contact; the only motion keeping both is a
    turn about the point where their normal lines meet, the pivot. It lifts the far support
    contact when the pushing force's moment about the pivot has the sense of the region's
    tipping (clockwise for the right region): the paper's criterion (section 2.4) with the
    support contact moved to the pivot, the same point when the holding tip sits at the
    support contact. Per holding contact the largest pushing arm counts, and the smallest of
    these over the holding contacts; ``-inf`` where a finger does not touch or the holding
    contact cannot hold (its force does not push towards the far support contact)."""
    sense = 1.0 if hold == 2 else -1.0  # right region: a clockwise (negative) moment tips
    held = [c for c in state.contacts if c.body == f"finger{hold}"]
    push = [c for c in state.contacts if c.body == f"finger{3 - hold}"]
    if not held or not push or any(sense * c.normal[0] >= 0.0 for c in held):
        return -math.inf
    x_C = region.contact_W[0]
    arms = []
    for c in held:
        pivot = c.point + (x_C - c.point[0]) / c.normal[0] * c.normal
        arms.append(max(-sense * float(geo.cross2(f.point - pivot, f.normal)) for f in push))
    return min(arms)


def scoop_placement(sim: Simulator, palm_angle: float = 0.0) -> State | None:
    """Pre-liftoff placement with both fingertips low at the support, just outside the
    object, the fingers inclined inward, each then closed until it first touches the object.

    Closing turns an inclined finger's tip inward and up, so the first contacts are on the
    object's lowest faces: where those overhang (their normals point up), they lie in the
    tippability regions and squeezing lifts the object off the support between the tips
    rather than tipping it. The palm pose follows from the tips (two circles about them, the
    joints a palm width apart at ``palm_angle``). Returned if a finger's first contact lies
    in the region its push tips (finger 1 in the right region, finger 2 in the left), the
    hand clears the support and the object, and squeezing moves the object
    (:func:`squeeze_tips`); else None."""
    scene = sim.scene
    q_obj = scene.object.start_pose.copy()
    obj = geo.transform(q_obj, scene.object.vertices_B)
    left, right = tippability_regions(scene)
    if left.is_empty and right.is_empty:
        return None
    gap = TIP_CLEARANCE * scene.palm.width
    # Tip heights: as low as the fingers' outer corners allow (they lie below the tips, by an
    # amount that depends on the inclination, hence a few rounds).
    y = np.array([f.thickness for f in scene.fingers]) + gap
    for _ in range(3):
        tips = np.array(
            [[_extent_above(obj, y[0])[0] - gap, y[0]], [_extent_above(obj, y[1])[1] + gap, y[1]]]
        )
        h = _hand_through_tips(scene, tips[0], tips[1], palm_angle)
        if h is None:
            return None
        lowest = np.array([p[:, 1].min() for p in kin.hand_polygons_W(scene, h)[1:]])
        y += gap - lowest
    if kin.hand_placement_problem(scene, q_obj, h, 0.0) is not None:
        return None
    support = _support_polygon(obj, scene.palm.width)
    for finger in (1, 2):
        q = _first_touch(scene, h, finger, q_obj, support, start=h[2 + finger])
        if q is None:
            return None
        h[2 + finger] = q
    if kin.hand_placement_problem(scene, q_obj, h, sim.tol) is not None:
        return None
    try:
        state = sim.settle(q_obj, h)
    except ComputationError:
        return None
    if np.abs(state.object_pose - q_obj).max() > 1e-9 * sim.size:
        return None
    in_region = any(
        all(region.contains(c.point, c.normal, 1e-7) for c in touch)
        for finger, region in ((1, right), (2, left))
        if not region.is_empty
        and (touch := [c for c in state.contacts if c.body == f"finger{finger}"])
    )
    return state if in_region and squeeze_tips(sim, state)[0] else None


def _extent_above(vertices: np.ndarray, y: float) -> tuple[float, float]:
    """Least and greatest x of the part of a convex polygon at heights >= ``y``."""
    xs = list(vertices[vertices[:, 1] >= y, 0])
    for a, b in zip(vertices, geo.following(vertices), strict=True):
        if (a[1] - y) * (b[1] - y) < 0:  # the edge crosses the height y
            xs.append(a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]))
    if not xs:
        return float(vertices[:, 0].min()), float(vertices[:, 0].max())
    return min(xs), max(xs)


def _hand_through_tips(
    scene, tip1: np.ndarray, tip2: np.ndarray, palm_angle: float
) -> np.ndarray | None:
    """Hand configuration with the fingertips at ``tip1`` and ``tip2``, the palm at
    ``palm_angle`` and above the tips, and both fingers pointing down and inward in the world
    (their tips below and inside their joints, so that closing raises them); None if there
    is none within the joint limits."""
    w = scene.palm.width
    u = np.array([math.cos(palm_angle), math.sin(palm_angle)])
    L1, L2 = (f.length for f in scene.fingers)
    # joint 1 lies on the circle of radius L1 about tip 1 and (joint 2 = joint 1 + w u) on the
    # circle of radius L2 about tip 2 shifted by -w u
    c1, c2 = tip1, tip2 - w * u
    d = float(np.linalg.norm(c2 - c1))
    if d == 0.0 or d > L1 + L2 or d < abs(L1 - L2):
        return None
    a = (L1 * L1 - L2 * L2 + d * d) / (2 * d)
    off = math.sqrt(max(L1 * L1 - a * a, 0.0))
    e = (c2 - c1) / d
    mid = c1 + a * e
    joint1 = max((mid + off * geo.perp(e), mid - off * geo.perp(e)), key=lambda p: p[1])
    joint2 = joint1 + w * u
    q1 = math.atan2(*(tip1 - joint1)[::-1]) - palm_angle
    q2 = math.atan2(*(tip2 - joint2)[::-1]) - palm_angle
    q1, q2 = (math.remainder(q, 2 * math.pi) for q in (q1, q2))
    (x1, y1), (x2, y2) = tip1 - joint1, tip2 - joint2
    if not (y1 < 0.0 < x1 and y2 < 0.0 and x2 < 0.0):
        return None  # a finger not pointing down and inward: closing would drive its tip down
    centre = joint1 + 0.5 * w * u
    h = np.array([centre[0], centre[1], palm_angle, q1, q2])
    lim = scene.joint_limits
    return h if np.all(h[3:] >= lim[:, 0]) and np.all(h[3:] <= lim[:, 1]) else None


def _support_polygon(obj: np.ndarray, w: float) -> np.ndarray:
    """The support near the object, as a polygon (for first-touch tests)."""
    cx = float(obj[:, 0].mean())
    return np.array([[cx - 5 * w, -5 * w], [cx + 5 * w, -5 * w], [cx + 5 * w, 0], [cx - 5 * w, 0]])


def _side_direction(scene, p_C: np.ndarray, hold: int) -> np.ndarray:
    """Unit direction up the object's side from the support contact ``p_C``: along the edge
    that leaves ``p_C`` upwards on finger ``hold``'s side (finger 2: the right side)."""
    v = scene.object.vertices_W0
    k = int(np.argmin(np.linalg.norm(v - p_C, axis=1)))
    other = v[(k + 1) % len(v)] if hold == 2 else v[k - 1]
    d = other - v[k]
    return d / np.linalg.norm(d)


def squeeze_tips(sim: Simulator, state: State, dq: float = 1e-3) -> tuple[bool, list[int]]:
    """Whether squeezing the fingers at equal rates moves the object (the velocity LP, eqs.
    19-21, has a solution with nonzero velocity), and which support contacts break at the
    onset (zero dual value in the force LP), as indices into ``state.contacts``."""
    p, n, b = state.contact_arrays()
    dh = np.array([0.0, 0.0, 0.0, dq, -dq])
    V = mech.V_ob(p, n, state.object_pose[:2])
    xi = mech.xi(sim.scene, state.hand, dh, b, p, n)
    # In the simulator's units (moments per palm width, velocities per palm width), whose
    # LP tolerances are unit-free; the twist comes back as (v_x / w, v_y / w, omega).
    w = sim.scene.palm.width
    res = motion_lp(V * sim.model.per_length, xi / w, sim.scene.object_weight)
    if res.status != "optimal":
        return False, []
    moves = np.abs(res.velocity).max() * w > 1e-9 * sim.size
    weight = sim.scene.object_weight
    broken = [
        i
        for i, (c, f) in enumerate(zip(state.contacts, res.forces, strict=True))
        if c.body == "support" and f <= 1e-9 * weight
    ]
    return bool(moves), broken
