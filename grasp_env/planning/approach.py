"""Collision-free hand paths to a planned pre-liftoff placement (the scripted policy
drives the hand along them before lifting)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.state import State
from grasp_env.errors import ComputationError
from grasp_env.simulator import Simulator

#: Finger openings (rad) from the placement's finger angles tried by :func:`approach_path`
#: for the final descent, and the margin (palm widths) it keeps from the object in transit.
#: A negative opening closes the finger further: the tip of a finger turned inward past the
#: vertical rises, where opening it would swing the tip down into the support.
APPROACH_OPENINGS = (0.3, 0.6, 0.15, 1.0, 0.0, -0.3, -0.6)

#: Which fingers are opened by those amounts for the descent: both, or one alone (a finger
#: whose tip rests on the support at the target, turned past the vertical, would swing its
#: tip into the support if opened).
APPROACH_OPEN_FINGERS = (np.array([1.0, 1.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0]))

APPROACH_MARGIN = 0.02

#: Path resolution of the clearance check, in palm widths and radians.
APPROACH_RESOLUTION = 0.005


def _segment_clear(scene, a: np.ndarray, b: np.ndarray, q_obj: np.ndarray, tol: float) -> bool:
    """The hand moving in a straight line from ``a`` to ``b`` (hand configurations) keeps
    clear of the object and the support (up to ``tol``) at every checked sample."""
    d = b - a
    w = scene.palm.width
    span = max(float(np.abs(d[:2]).max()) / w, float(np.abs(d[2:]).max()) * 0.5)
    n = max(1, math.ceil(span / APPROACH_RESOLUTION))
    return all(
        kin.hand_placement_problem(scene, q_obj, a + (k / n) * d, tol) is None
        for k in range(1, n + 1)
    )


def approach_path(sim: Simulator, state: State, target: np.ndarray) -> list[np.ndarray] | None:
    """A collision-free hand path from ``state`` (object resting at its pose) to the
    pre-liftoff hand ``target``, as hand configurations reached by straight-line moves.

    The fingers open to their limits, the palm rises clear of the object, moves and turns to
    above the target with the fingers opened a little from the target's, descends to the
    target palm pose, and the fingers close to the target angles (:func:`_approach_paths`
    lists the variants, simplest first). The first path that the clearance check and then
    the simulator find free (the object does not move and the hand reaches ``target``) is
    returned, without the start configuration; None if there is none.
    """
    q_obj = state.object_pose
    tol = 1e-6 * sim.size
    tried = set()
    for path in _approach_paths(sim.scene, state.hand, target, q_obj, tol):
        path = [h for i, h in enumerate(path) if i == 0 or np.any(h != path[i - 1])]
        key = np.concatenate(path).tobytes()
        if key in tried:
            continue
        tried.add(key)
        if _path_clear(sim.scene, state.hand, path, q_obj, tol) and _path_moves_nothing(
            sim, state, path
        ):
            return path
    return None


def _approach_paths(scene, start: np.ndarray, target: np.ndarray, q_obj: np.ndarray, tol: float):
    """Candidate approach paths (possibly repeated). First the simple ones: both fingers
    opened by each of ``APPROACH_OPENINGS`` (>= 0), descending along the world vertical or the
    target palm's normal straight onto the target palm pose. Then the refined ones: one finger
    opened alone or closed further, the palm also descending along a finger's axis towards its
    tip (a fingertip slides into a corner under an overhang), opened fingers that would dip
    into the support or the object at the target palm pose opened a little higher up (closing
    as the palm comes down), and the fingers closed once the palm is above the target rather
    than on the way."""
    w = scene.palm.width
    lim = scene.joint_limits
    top = float(geo.transform(q_obj, scene.object.vertices_B)[:, 1].max()) + APPROACH_MARGIN * w
    opened = start.copy()
    opened[3] = lim[0, 0] + 0.05
    opened[4] = lim[1, 1] - 0.05
    th = float(target[2])
    both = APPROACH_OPEN_FINGERS[0]
    simple = [(d, both) for d in APPROACH_OPENINGS if d >= 0.0]
    refined = [
        (d, which)
        for d, which in itertools.product(APPROACH_OPENINGS, APPROACH_OPEN_FINGERS)
        if d != 0.0 or which is both  # nothing opened: one candidate
    ]
    for is_refined, combos in ((False, simple), (True, refined)):
        for delta, which in combos:
            low = target.copy()
            low[3:] = np.clip(target[3:] + delta * np.array([-1.0, 1.0]) * which, *lim.T)
            directions = [np.array([0.0, 1.0]), np.array([-math.sin(th), math.cos(th)])]
            if is_refined:
                axes = kin.body_poses_W(scene, low)[1:3, :2] - kin.fingertips_W(scene, low)
                directions += [a / np.linalg.norm(a) for a in axes if a[1] > 0.0]
            for direction in directions:
                near = low
                if is_refined:
                    near = _slide(low, direction, 0.5 * w, 0.01 * w, _clear_of(scene, q_obj, tol))
                above = _slide(low, direction, 3.0 * w, 0.02 * w, _above(scene, top))
                if near is None or above is None:
                    continue
                raised = opened.copy()
                raised[1] = max(above[1], opened[1])
                yield [opened, raised, above, near, target.copy()]
                if not is_refined:
                    continue
                # close the fingers above the target, raised until their sweep is clear
                sweep_clear = _sweep_clear(scene, opened[3:], q_obj, tol)
                closed = _slide(above, direction, 3.0 * w, 0.05 * w, sweep_clear)
                if closed is not None:
                    lifted = raised.copy()
                    lifted[1] = max(raised[1], closed[1])
                    still_open = np.r_[closed[:3], opened[3:]]
                    yield [opened, lifted, still_open, closed, near, target.copy()]


def _slide(h: np.ndarray, direction: np.ndarray, length: float, step: float, accept):
    """The first configuration ``h`` with the palm moved along ``direction`` by a multiple of
    ``step`` (0 first, below ``length``) that ``accept`` takes; None if there is none."""
    for s in np.arange(0.0, length, step):
        moved = h.copy()
        moved[:2] += s * direction
        if accept(moved):
            return moved
    return None


def _clear_of(scene, q_obj: np.ndarray, tol: float):
    return lambda h: kin.hand_placement_problem(scene, q_obj, h, tol) is None


def _sweep_clear(scene, opened_fingers: np.ndarray, q_obj: np.ndarray, tol: float):
    """Whether the fingers close clear from ``opened_fingers`` to ``h``'s angles, the palm
    at ``h``."""
    return lambda h: _segment_clear(scene, np.r_[h[:3], opened_fingers], h, q_obj, 10 * tol)


def _above(scene, height: float):
    return lambda h: min(p[:, 1].min() for p in kin.hand_polygons_W(scene, h)) > height


def _path_clear(scene, start: np.ndarray, path: list, q_obj: np.ndarray, tol: float) -> bool:
    """Every straight segment of ``path`` from ``start`` passes the clearance check (the
    last, onto the target, with the tight tolerance: the target touches the object)."""
    a = start
    for b in path:
        if not _segment_clear(scene, a, b, q_obj, tol if b is path[-1] else 10 * tol):
            return False
        a = b
    return True


def _path_moves_nothing(sim: Simulator, state: State, path: list[np.ndarray]) -> bool:
    start = state
    try:
        for h in path:
            state = sim.move_hand(state, palm=h[:3], fingers=h[3:])
    except ComputationError:
        return False
    return bool(
        np.abs((state.hand - path[-1]) / kin.hand_units(sim.scene)).max()
        < 1e-9 * sim.size / sim.scene.palm.width
        and np.abs(state.object_pose - start.object_pose).max() < 1e-9 * sim.size
    )
