"""agents.planner_agents.PlannerHandover: the planner where its lifting works, the agent
where it gets stuck."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("rl_zoo3")  # the train extra

import grasp_env  # noqa: F401  (registers the env ids)
from agents import train_ppo
from agents.episodes import LIFT_KWARGS, PolicySpec, make_env
from agents.models import shipped_name
from agents.planner_agents import PlannerHandover
from agents.planner_base import planner_wrapper
from agents.scripted import ScriptedPolicy

ROOT = Path(__file__).resolve().parents[2]
#: Held-out lifting shapes: lifting from the placement with the palm fixed reaches form
#: closure for the first and gets stuck for the second.
LIFTS, STUCK = 1_000_001, 1_000_012


def _lift_env(**kwargs) -> gym.Env:
    settings = {"palm_control": True, "hand_features": True, "max_episode_steps": 200}
    return gym.make("FrictionlessGrasp-v0", **{**settings, **LIFT_KWARGS, **kwargs})


def _hands(env, actions, seed):
    """Play ``actions`` (a function of the step) from ``reset(seed)``: the hands and the last
    info."""
    env.reset(seed=seed)
    hands = [env.unwrapped.state.hand.copy()]
    for k in range(200):
        _, _, terminated, truncated, info = env.step(actions(k))
        hands.append(env.unwrapped.state.hand.copy())
        if terminated or truncated:
            break
    return np.array(hands), info


def _random_actions(seed):
    rng = np.random.default_rng(seed)
    table = rng.uniform(-1.0, 1.0, (200, 5)).astype(np.float32)
    return lambda k: table[k]


def test_where_lifting_works_the_planner_plays_whatever_the_agent_sends():
    # the planner alone, palm fixed, on the plain env
    env = _lift_env()
    obs, info = env.reset(seed=LIFTS)
    policy = ScriptedPolicy(env, fallbacks=False)
    policy.reset(obs, info)
    assert policy.plan.success
    hands = [env.unwrapped.state.hand.copy()]
    while True:
        obs, _, terminated, truncated, expected = env.step(policy.act(obs))
        hands.append(env.unwrapped.state.hand.copy())
        if terminated or truncated:
            break
    assert expected["is_success"]
    wrapped = PlannerHandover(_lift_env())
    _, info = wrapped.reset(seed=LIFTS)
    assert info["planner_plays"]
    got, got_info = _hands(wrapped, _random_actions(3), LIFTS)
    assert got_info["planner_plays"] and got_info["is_success"]
    np.testing.assert_array_equal(got, np.array(hands))


def test_where_lifting_gets_stuck_the_agent_plays_every_action():
    actions = _random_actions(5)
    expected, _ = _hands(_lift_env(), actions, STUCK)
    wrapped = PlannerHandover(_lift_env())
    _, info = wrapped.reset(seed=STUCK)
    assert not info["planner_plays"]
    got, got_info = _hands(wrapped, actions, STUCK)
    assert not got_info["planner_plays"]
    np.testing.assert_array_equal(got, expected)
    # and there the planner's lifting alone, checked apart, does not reach form closure
    env = _lift_env()
    obs, info = env.reset(seed=STUCK)
    policy = ScriptedPolicy(env, fallbacks=False)
    policy.reset(obs, info)
    assert not policy.plan.success


def test_redraw_keeps_only_shapes_where_lifting_gets_stuck():
    wrapped = PlannerHandover(_lift_env(), redraw=True)
    wrapped.reset(seed=0)
    for _ in range(4):
        _, info = wrapped.reset()
        assert not info["planner_plays"]
        # the planner's lifting from this very state, planned apart, gets stuck
        base = wrapped.unwrapped
        probe = _lift_env()
        probe.reset(options={"scene": base.scene})
        np.testing.assert_array_equal(probe.unwrapped.state.hand, base.state.hand)
        policy = ScriptedPolicy(probe, fallbacks=False)
        policy.reset()
        assert not policy.plan.success


def test_bad_input_is_named_and_the_env_stays_usable():
    with pytest.raises(ValueError, match="PlannerHandover needs palm_control=True"):
        PlannerHandover(_lift_env(palm_control=False))
    wrapped = PlannerHandover(_lift_env())
    wrapped.reset(seed=LIFTS)
    hand = wrapped.unwrapped.state.hand.copy()
    for bad in (np.full(5, np.nan), np.zeros(3), "go"):
        with pytest.raises(ValueError, match="action"):
            wrapped.step(bad)
    np.testing.assert_array_equal(wrapped.unwrapped.state.hand, hand)
    _, _, _, _, info = wrapped.step(np.zeros(5, np.float32))
    assert info["planner_plays"] and "sim_error" not in info
    # where the agent plays, the env's own checks name the action
    wrapped.reset(seed=STUCK)
    with pytest.raises(ValueError, match="action"):
        wrapped.step(np.full(5, np.inf))
    _, _, _, _, info = wrapped.step(np.zeros(5, np.float32))
    assert not info["planner_plays"]


def test_the_handover_config_names_the_wrapper_and_evaluation_plays_it():
    conf = ROOT / "configs" / "ppo_handover.yml"
    entry = train_ppo.prepare("FrictionlessGraspLift-v0", conf)
    assert planner_wrapper(entry) == (PlannerHandover, {"redraw": False})
    with pytest.raises(ValueError, match=r"no shipped model of configs/ppo_handover\.yml"):
        shipped_name(conf, "FrictionlessGraspLift-v0")
    spec = PolicySpec("ppo_x", "ppo", {"palm_control": True}, None, planner_wrapper(entry))
    env = make_env(spec, LIFT_KWARGS, 200)
    assert isinstance(env, PlannerHandover) and not env.redraw


def test_a_trained_agent_without_a_model_is_a_usage_error(tmp_path):
    out = subprocess.run(
        [
            sys.executable, "-m", "agents.train_ppo", "--env", "FrictionlessGraspLift-v0",
            "--conf-file", "configs/ppo_handover.yml", "--trained-agent", str(tmp_path),
        ],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 2
    assert "--trained-agent" in out.stderr and "no model.zip there" in out.stderr
