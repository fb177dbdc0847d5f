"""Exploratory lifting with palm motion, for objects the paper's fixed-palm lifting cannot lift.

The paper lifts with the palm fixed, by finger increments alone (:func:`grasp_env.planning.lift`).
Some objects cannot be lifted that way from any placement: a tall thin rectangle under a wide
hand tips over and lies down, out of reach of the fingertips. Lifting it takes a re-grasp with
palm motion: the palm turns so that the object slides onto one finger's link as onto a ramp,
the other fingertip pushes it up, and a last turn of the palm tips it onto the link, under
the palm. This module finds such motions by search.

The search follows Go-Explore (Ecoffet et al., Nature 590, 2021): an archive of cells, each
keeping the first state that reached it, where a cell is the object's height and angle, the
hand relative to the object and whether the object is off the support. Each round chooses a
cell (favouring cells chosen rarely and objects raised off the support) and takes a short
random walk of hand increments from its state; every new cell reached joins the archive. The
search ends at a state in form closure with the object off the support. The increments
(:func:`hand_increments`) are each finger alone and both together, palm translations, and
palm turns. A move the simulator
cannot follow, that does not move the hand, or that puts a lifted object back on the support
is refused (a jam or a hand blocked by the support stops short, deterministically, and
counts as a move). The search is seeded, so the same start gives the same path.

The path found is a random walk. :func:`shorten` replaces stretches of it by single straight
hand moves that reach the same object pose, replaying the rest of the path after each
replacement, so the result is still a chain of simulator moves that ends in the goal.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.state import State

#: Progress of the search (every :data:`PROGRESS_MOVES` moves) at INFO level.
log = logging.getLogger(__name__)
#: Moves between two progress lines.
PROGRESS_MOVES = 2000

#: A hand move: the state reached from ``state`` by the hand increment ``dh`` (shape (5,)),
#: or None when it is refused (the simulator cannot follow it, or the caller's rules).
Move = Callable[[State, np.ndarray], "State | None"]


@dataclass(frozen=True)
class IncrementSizes:
    """Sizes of the search's hand increments.

    Attributes:
        finger: finger angle increment (rad).
        palm: palm translation (palm widths).
        turn: palm rotation (rad).

    The defaults are at most one action of ``FrictionlessGrasp-v0`` at its default maximum
    increments.
    """

    finger: float = 0.05
    palm: float = 0.02
    turn: float = 0.04


@dataclass(frozen=True)
class ExploreResult:
    """How a search ended.

    Attributes:
        states: the path from the start to the goal (start included); None if not found.
        increments: ``increments[k]`` is the hand increment from ``states[k]`` to
            ``states[k + 1]``.
        moves: hand moves simulated.
        cells: cells in the archive at the end.
        root: index among the starts of the state the path begins at.
    """

    states: list[State] | None
    increments: list[np.ndarray]
    moves: int
    cells: int
    root: int = 0


def hand_increments(scene, sizes: IncrementSizes) -> list[np.ndarray]:
    """The search's hand increments: each finger alone and both together (same and opposite
    ways), palm translations along x and y, and palm turns either way about its centre, 14
    in all. (Turns about a finger's joint, that finger's link held still, were tried too: on
    tall_rectangle they made the search slower, 14033 moves instead of 1965 on one seed and
    none found within 20000 on another.)"""
    out = []
    for m in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, -1), (-1, 1), (1, 1), (-1, -1)):
        dh = np.zeros(5)
        dh[3:] = sizes.finger * np.array(m, float)
        out.append(dh)
    for v in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        dh = np.zeros(5)
        dh[:2] = sizes.palm * scene.palm.width * np.array(v, float)
        out.append(dh)
    for sign in (1.0, -1.0):
        dh = np.zeros(5)
        dh[2] = sign * sizes.turn
        out.append(dh)
    return out


def _lowest(state: State) -> float:
    """Height of the object's lowest vertex above the support."""
    return float(geo.transform(state.object_pose, state.scene.object.vertices_B)[:, 1].min())


def _cell(state: State) -> tuple:
    w = state.scene.palm.width
    q, h = state.object_pose, state.hand
    return (
        round(q[1] / (0.05 * w)),
        round(q[2] / 0.2),
        round((h[0] - q[0]) / (0.1 * w)),
        round(h[1] / (0.1 * w)),
        round(h[2] / 0.2),
        round(h[3] / 0.25),
        round(h[4] / 0.25),
        state.on_support,
    )


def explore_lift(
    starts: State | Sequence[State],
    move: Move,
    goal: Callable[[State], bool],
    *,
    sizes: IncrementSizes = IncrementSizes(),
    seed: int = 0,
    max_moves: int = 20000,
    palm_rise: float = 0.5,
    palm_reach: float = 1.2,
    max_palm_angle: float = 1.5,
) -> ExploreResult:
    """Search hand increments from ``starts`` for a state where ``goal`` holds.

    Args:
        starts: the state to start from, or several: the archive starts with all of them
            (one per cell, the first given), and the path found begins at one of them.
        move: simulates one hand increment (see :data:`Move`); it should return None for
            moves the caller refuses. The search refuses in addition moves that do not move
            the hand or put an object back on the support once it has left it (a drop).
        goal: the goal test.
        sizes: increment sizes.
        seed: seed of the search's random choices.
        max_moves: budget of simulated moves.
        palm_rise: the palm stays at most this many palm widths above its highest start.
        palm_reach: the palm's centre stays within this many palm widths of the object's
            centre of mass horizontally.
        max_palm_angle: the palm angle stays within +- this (rad).

    Returns:
        The path found (or None) and the search's effort.
    """
    starts = [starts] if isinstance(starts, State) else list(starts)
    scene = starts[0].scene
    w = scene.palm.width
    rng = np.random.default_rng(seed)
    increments = hand_increments(scene, sizes)
    y_max = max(st.hand[1] for st in starts) + palm_rise * w
    # tree of states: (state, parent index, increment from the parent); the starts are roots
    nodes: list[tuple[State, int, np.ndarray | None]] = [(st, -1, None) for st in starts]
    archive: dict[tuple, int] = {}
    for i, st in enumerate(starts):
        archive.setdefault(_cell(st), i)
    chosen: dict[tuple, int] = {}
    moves = 0
    units = kin.hand_units(starts[0].scene)

    def weight(cell: tuple) -> float:
        lift = max(_lowest(nodes[archive[cell]][0]), 0.0) / w
        return 1.0 / math.sqrt(1 + chosen.get(cell, 0)) + 3.0 * lift + 0.1 * rng.random()

    while moves < max_moves:
        cells = list(archive)
        pick = rng.choice(len(cells), min(32, len(cells)), replace=False)
        cell = max((cells[i] for i in pick), key=weight)
        chosen[cell] = chosen.get(cell, 0) + 1
        index = archive[cell]
        state = nodes[index][0]
        for _ in range(int(rng.integers(1, 4))):  # a walk of 1-3 straight stretches
            dh = increments[int(rng.integers(0, len(increments)))]
            for _ in range(int(rng.integers(1, 5))):
                if moves >= max_moves:
                    break
                moves += 1
                if moves % PROGRESS_MOVES == 0:
                    log.info("  explored %d of %d moves (%d cells)", moves, max_moves, len(archive))
                h = state.hand + dh
                if (
                    h[1] > y_max
                    or abs(h[0] - state.object_pose[0]) > palm_reach * w
                    or abs(h[2]) > max_palm_angle
                ):
                    break
                new = move(state, dh)
                if new is None:
                    break
                if np.abs((new.hand - state.hand) / units).max() <= 1e-12:
                    break
                if new.on_support and not state.on_support:
                    break
                nodes.append((new, index, dh))
                index, state = len(nodes) - 1, new
                archive.setdefault(_cell(new), index)
                if goal(new):
                    return _result(nodes, index, moves, len(archive))
            else:
                continue
            break  # a refused move ends the walk
    return ExploreResult(None, [], moves, len(archive))


def _result(nodes: list, index: int, moves: int, cells: int) -> ExploreResult:
    chain = []
    while index >= 0:
        chain.append(index)
        index = nodes[index][1]
    chain.reverse()
    states = [nodes[i][0] for i in chain]
    increments = [nodes[i][2] for i in chain[1:]]
    return ExploreResult(states, increments, moves, cells, root=chain[0])


def shorten(
    states: list[State],
    increments: list[np.ndarray],
    move: Move,
    goal: Callable[[State], bool],
    pose_tol: float = 1e-9,
) -> tuple[list[State], list[np.ndarray]]:
    """Shortcut a path: from each state, the farthest later state (tried at halving
    distances) that one straight hand move reaches with the same object pose (to
    ``pose_tol`` palm widths) and the same touching bodies replaces the stretch between
    them; the rest of the path is replayed from there by its increments and the shortcut is
    kept only if the replay still ends in the goal. Returns the new states and increments."""
    states, increments = list(states), list(increments)
    tol = pose_tol * states[0].scene.palm.width
    i = 0
    while i < len(states) - 2:
        last = len(states) - 1
        for j in _halvings(i, last):
            dh = states[j].hand - states[i].hand
            new = move(states[i], dh)
            if not _same(new, states[j], tol):
                continue
            tail = _replay(new, increments[j:], move)
            if tail is None or not goal(tail[-1]):
                continue
            states = states[: i + 1] + tail
            increments = [*increments[:i], dh, *increments[j:]]
            break
        i += 1
    return states, increments


def _halvings(i: int, last: int) -> list[int]:
    """Candidate shortcut ends from ``i``: ``last``, then halfway back towards ``i``, and so
    on down to ``i + 2``."""
    out, span = [], last - i
    while span >= 2:
        out.append(i + span)
        span //= 2
    return out


def _same(new: State | None, ref: State, tol: float) -> bool:
    if new is None:
        return False
    if np.abs(new.hand - ref.hand).max() > 1e-12 * ref.scene.palm.width:
        return False
    if np.abs(new.object_pose - ref.object_pose).max() > tol:
        return False
    return sorted(c.body for c in new.contacts) == sorted(c.body for c in ref.contacts)


def _replay(state: State, increments: list[np.ndarray], move: Move) -> list[State] | None:
    """``state`` and the states the increments lead to from it; None if a move is refused or
    drops the object."""
    out = [state]
    for dh in increments:
        new = move(out[-1], dh)
        if new is None:
            return None
        if new.on_support and not out[-1].on_support:
            return None
        out.append(new)
    return out
