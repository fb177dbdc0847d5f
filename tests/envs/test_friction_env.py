"""The env's ``friction`` argument: a step whose hand motion friction can resist jams there.

The decision is checked against :func:`grasp_env.critical_friction` of the state and the
step's hand motion, and its effect against the frictionless env: a jammed step leaves the
hand and the object where they were, any other step is the frictionless env's to the bit.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from vector_checks import lockstep

import grasp_env

CLOSE = np.array([1.0, 1.0])


def closing_run(friction: float, steps: int = 40):
    """fig13 from the centred pre-liftoff placement, both fingers closing at full rate."""
    env = gym.make("FrictionlessGrasp-v0", start="preliftoff", friction=friction)
    env.reset(seed=0)
    out = []
    for _ in range(steps):
        before = env.unwrapped.state
        obs, reward, terminated, truncated, info = env.step(CLOSE)
        out.append((before, env.unwrapped.state, obs, reward, info))
        if terminated or truncated:
            break
    return out, env.unwrapped.simulator


@pytest.mark.parametrize("mu", [0.2, 0.47, 0.55, 1.0])
def test_a_step_jams_exactly_where_its_critical_friction_is_reached(mu: float) -> None:
    """Every step of the closing: jammed iff mu* of its start state and hand motion (the
    motion the frictionless env makes from there) is at most mu; a jammed step keeps the
    state, any other moves as without friction."""
    run, sim = closing_run(mu)
    for before, after, _, _, info in run:
        step = 0.05  # max_finger_step: the fingers close by it, within the joint limits
        low, high = before.scene.joint_limits.T
        fingers = np.clip(before.hand[3:] + np.array([step, -step]), low, high)
        expected_state = sim.move_hand(before, fingers=fingers)
        motion = np.r_[0.0, 0.0, 0.0, fingers - before.hand[3:]]
        critical = grasp_env.critical_friction(before, motion)
        assert info["friction_jam"] == (critical <= mu), critical
        if info["friction_jam"]:
            assert info["jammed"]
            np.testing.assert_array_equal(after.hand, before.hand)
            np.testing.assert_array_equal(after.object_pose, before.object_pose)
        else:
            np.testing.assert_array_equal(after.hand, expected_state.hand)
            np.testing.assert_array_equal(after.object_pose, expected_state.object_pose)


def test_friction_below_the_plan_s_least_critical_value_changes_nothing() -> None:
    """fig13's squeeze needs about 0.46 to jam (docs/friction.md): with 0.2 the episode is
    the frictionless one, observation for observation, until form closure."""
    (plain, _), (rough, _) = closing_run(0.0), closing_run(0.2)
    for (_, _, o0, r0, i0), (_, _, o1, r1, i1) in zip(plain, rough, strict=True):
        if i1["friction_jam"]:
            assert i0["is_success"]  # only a form-closed grasp resists the squeeze
            break
        np.testing.assert_array_equal(o0, o1)
        assert r0 == r1
    assert any(i["is_success"] for *_, i in rough)


def test_a_large_friction_jams_the_first_squeeze() -> None:
    run, _ = closing_run(0.6, steps=5)
    assert all(info["friction_jam"] for *_, info in run)
    assert not any(info["is_success"] for *_, info in run)


def test_simulate_action_is_the_step_with_friction() -> None:
    env = gym.make("FrictionlessGrasp-v0", start="preliftoff", friction=0.55)
    env.reset(seed=0)
    base = env.unwrapped
    for _ in range(6):
        predicted = base.simulate_action(base.state, CLOSE)
        _, _, _, _, info = env.step(CLOSE)
        assert predicted.jammed == info["jammed"]
        np.testing.assert_array_equal(predicted.hand, base.state.hand)
        np.testing.assert_array_equal(predicted.object_pose, base.state.object_pose)


def test_the_batched_env_jams_as_the_single_one() -> None:
    """Sub-env i of ``make_vec`` with friction follows a single env reset with seed + i."""
    jams = 0
    for i, info, infos, _ in lockstep("FrictionlessGraspLift-v0", 3, 40, friction=0.4):
        assert info["friction_jam"] == infos["friction_jam"][i]
        assert info["jammed"] == infos["jammed"][i]
        jams += info["friction_jam"]
    assert jams > 0


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf, 2e6])
def test_a_bad_friction_is_refused_by_name(bad: float) -> None:
    with pytest.raises(ValueError, match="friction"):
        gym.make("FrictionlessGrasp-v0", friction=bad)


@pytest.mark.parametrize("bad", ["0.3", None, True])
def test_a_friction_that_is_not_a_number_is_refused_by_name(bad) -> None:
    with pytest.raises(TypeError, match="friction"):
        gym.make("FrictionlessGrasp-v0", friction=bad)


def test_without_friction_the_info_is_as_before() -> None:
    env = gym.make("FrictionlessGrasp-v0")
    env.reset(seed=0)
    assert "friction_jam" not in env.step(CLOSE)[4]
