"""Exploratory lifting with palm motion (grasp_env.planning.regrasp): increments, search,
shortcuts."""

from __future__ import annotations

import numpy as np
import pytest
from test_planner import _check_grasp

import grasp_env
from grasp_env import planning
from grasp_env.planning import regrasp

SIZES = regrasp.IncrementSizes()


@pytest.fixture(scope="module")
def fig13():
    sim = grasp_env.Simulator("fig13")
    return sim, planning.centred_placement(sim)


def _move(sim):
    def move(state, dh):
        h = state.hand + dh
        return planning.try_move(sim, state, palm=h[:3], fingers=h[3:])

    return move


def test_hand_increments_are_single_moves_of_one_kind():
    scene = grasp_env.load_scene("fig13")
    incs = np.array(regrasp.hand_increments(scene, SIZES))
    assert incs.shape == (14, 5)
    assert len({tuple(d) for d in incs}) == 14  # all different
    for dh in incs:  # fingers only, palm translation only, or palm turn only
        moved = [bool(np.any(dh[3:])), bool(np.any(dh[:2])), bool(dh[2])]
        assert sum(moved) == 1
    assert np.abs(incs[:, 3:]).max() == SIZES.finger
    assert np.abs(incs[:, :2]).max() == SIZES.palm * scene.palm.width
    assert np.abs(incs[:, 2]).max() == SIZES.turn
    for dh in incs:  # each has its opposite
        assert any(np.array_equal(-dh, other) for other in incs)


def test_explore_lift_finds_a_grasp_that_replays_exactly(fig13):
    sim, start = fig13
    move = _move(sim)
    found = regrasp.explore_lift(start, move, planning.grasped, seed=0, max_moves=2000)
    assert found.states is not None and found.moves <= 2000
    assert len(found.increments) == len(found.states) - 1
    _check_grasp(found.states[-1])  # form closure checked by an independent LP
    state = start
    for dh, expected in zip(found.increments, found.states[1:], strict=True):
        state = move(state, dh)
        np.testing.assert_array_equal(state.object_pose, expected.object_pose)
        np.testing.assert_array_equal(state.hand, expected.hand)
    lifted = [not s.on_support for s in found.states]
    assert lifted == sorted(lifted)  # once off the support, never back on it (no drop)


def test_explore_lift_is_seeded(fig13):
    sim, start = fig13
    runs = [
        regrasp.explore_lift(start, _move(sim), planning.grasped, seed=s, max_moves=2000)
        for s in (3, 3, 4)
    ]
    same = [np.array([s.hand for s in r.states]) for r in runs]
    np.testing.assert_array_equal(same[0], same[1])
    assert same[0].shape != same[2].shape or not np.array_equal(same[0], same[2])


def test_explore_lift_keeps_to_its_budget(fig13):
    sim, start = fig13
    found = regrasp.explore_lift(start, _move(sim), lambda s: False, seed=0, max_moves=120)
    assert found.states is None and found.increments == []
    assert found.moves == 120 and found.cells >= 2


def test_shorten_keeps_a_chain_of_moves_that_ends_in_form_closure(fig13):
    sim, start = fig13
    move = _move(sim)
    found = regrasp.explore_lift(start, move, planning.grasped, seed=0, max_moves=2000)
    states, incs = regrasp.shorten(found.states, found.increments, move, planning.grasped)
    assert len(states) < len(found.states)  # this walk has detours to cut
    assert states[0] is start and len(incs) == len(states) - 1
    _check_grasp(states[-1])
    state = start
    for dh, expected in zip(incs, states[1:], strict=True):
        state = move(state, dh)
        np.testing.assert_array_equal(state.object_pose, expected.object_pose)


def test_planner_does_not_explore_when_a_placement_lifts():
    # fig13 lifts from the paper's placement: the palm never moves.
    plan = planning.plan_grasp("fig13", adjust=False)
    assert plan.success and plan.placement == "centred"
    palm = plan.steps[0].state.palm_pose
    assert all(np.array_equal(st.state.palm_pose, palm) for st in plan.steps)


@pytest.mark.slow
def test_planner_lifts_tall_rectangle_by_exploring():
    # Every placement gets stuck (the object lies down); exploratory lifting, from the states
    # those attempts passed through, turns the palm and lifts it (docs/reproduction.md).
    plan = planning.plan_grasp("tall_rectangle")
    assert plan.success, plan.message
    assert plan.placement.endswith(", exploratory lifting")
    lifting = [st for st in plan.steps if st.phase == "lifting"]
    assert all(st.note.startswith("explore") for st in lifting)
    palm = plan.steps[0].state.palm_pose
    assert any(not np.allclose(st.state.palm_pose, palm) for st in lifting)
    _check_grasp(lifting[-1].state)


def test_explore_lift_starts_from_every_root_and_says_which(fig13):
    # The archive starts with several states; the path found begins at the one named.
    sim, start = fig13
    move = _move(sim)
    other = move(start, np.array([0.0, 0.0, 0.0, 0.05, -0.05]))
    found = regrasp.explore_lift([other, start], move, planning.grasped, seed=0, max_moves=2000)
    assert found.states is not None
    assert found.states[0] is (other, start)[found.root]
    state = found.states[0]
    for dh, expected in zip(found.increments, found.states[1:], strict=True):
        state = move(state, dh)
        np.testing.assert_array_equal(state.object_pose, expected.object_pose)
