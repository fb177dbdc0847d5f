"""agents.planner_agents: residual and grip agents, a correction added to the scripted
planner's actions."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("rl_zoo3")  # the train extra

import grasp_env  # noqa: F401  (registers the env ids)
from agents import train_ppo
from agents.episodes import LIFT_KWARGS, PolicySpec, make_env
from agents.models import shipped_name
from agents.planner_agents import PlannerGrip, PlannerResidual
from agents.planner_base import planner_wrapper
from agents.scripted import ScriptedPolicy
from grasp_env.errors import WorkLimitError
from grasp_env.mechanics.closure import grip_objective, is_form_closure

ROOT = Path(__file__).resolve().parents[2]
#: Held-out lifting shapes (agents.evaluate's ``lift`` suite): lifting from the placement
#: succeeds for the first; it gets stuck for the second, where the planner explores with palm
#: motion (about 3 s of search).
LIFTS, STUCK = 1_000_001, 1_000_012


def _lift_env(**kwargs) -> gym.Env:
    return gym.make(
        "FrictionlessGrasp-v0",
        palm_control=True,
        hand_features=True,
        max_episode_steps=200,
        **LIFT_KWARGS,
        **kwargs,
    )


class _Sent(gym.Wrapper):
    """Records the actions that reach the env."""

    def __init__(self, env):
        super().__init__(env)
        self.sent = []

    def step(self, action):
        self.sent.append(np.array(action))
        return self.env.step(action)


def _play(env, act, seed):
    obs, info = env.reset(seed=seed)
    hands = [env.unwrapped.state.hand.copy()]
    while True:
        obs, _, terminated, truncated, info = env.step(act(obs))
        hands.append(env.unwrapped.state.hand.copy())
        if terminated or truncated:
            return info, np.array(hands)


def test_a_zero_correction_is_the_planner():
    env = _lift_env()
    policy = ScriptedPolicy(env)

    def planner(obs):
        return policy.act(obs)

    obs, info = env.reset(seed=LIFTS)
    policy.reset(obs, info)
    hands = [env.unwrapped.state.hand.copy()]
    while True:
        obs, _, terminated, truncated, expected = env.step(planner(obs))
        hands.append(env.unwrapped.state.hand.copy())
        if terminated or truncated:
            break
    assert expected["is_success"]
    got, got_hands = _play(PlannerResidual(_lift_env()), lambda obs: np.zeros(5), LIFTS)
    assert got["is_success"]
    assert got["grip_force"] == expected["grip_force"]
    np.testing.assert_array_equal(got_hands, np.array(hands))


def test_the_env_receives_the_planner_action_plus_the_scaled_correction_clipped():
    sent = _Sent(_lift_env())
    env = PlannerResidual(sent, scale=0.5)
    obs, _ = env.reset(seed=LIFTS)
    assert env.observation_space.shape == (sent.observation_space.shape[0] + 5,)
    rng = np.random.default_rng(0)
    expected = []
    for _ in range(30):
        correction = rng.uniform(-1, 1, 5).astype(np.float32)
        assert env.observation_space.contains(obs)
        base = obs[-5:]
        expected.append(np.clip(base + np.float32(0.5) * correction, -1, 1))
        obs, _, terminated, truncated, _ = env.step(correction)
        assert not (terminated or truncated)
    np.testing.assert_array_equal(np.array(sent.sent), np.array(expected, np.float32))
    # the planner closes the fingers first: its actions are not all zero
    assert np.abs(np.array(expected)[:, :2]).max() > 0.1


class _Rewards(gym.Wrapper):
    """Records the env's own rewards."""

    def __init__(self, env):
        super().__init__(env)
        self.rewards = []

    def step(self, action):
        out = self.env.step(action)
        self.rewards.append(out[1])
        return out


@pytest.mark.parametrize("seed", [LIFTS, STUCK])
def test_the_correction_cost_charges_the_correction_that_acts(seed):
    inner = _Rewards(_lift_env())
    env = PlannerResidual(inner, correction_cost=0.3)
    env.reset(seed=seed)
    rng = np.random.default_rng(1)
    for _ in range(20):
        correction = rng.uniform(-1, 1, 5).astype(np.float32)
        _, reward, _, _, info = env.step(correction)
        # by hand: the 5 squares, or nothing where the planner replays its fallback
        squares = 0.0 if seed == STUCK else sum(float(c) ** 2 for c in correction)
        assert reward == pytest.approx(inner.rewards[-1] - 0.3 * squares, rel=1e-6, abs=1e-9)
        assert info.get("reward_correction", 0.0) == pytest.approx(-0.3 * squares, rel=1e-6)
    assert env.policy.on_fallback == (seed == STUCK)


def test_on_the_planner_fallback_the_correction_is_ignored():
    sent = _Sent(_lift_env())
    env = PlannerResidual(sent)
    obs, _ = env.reset(seed=STUCK)
    assert env.policy.on_fallback  # lifting from the placement got stuck: it explores
    bases = []
    while True:
        bases.append(obs[-5:].copy())
        obs, _, terminated, truncated, info = env.step(np.ones(5, np.float32))
        if terminated or truncated:
            break
    np.testing.assert_array_equal(np.array(sent.sent), np.array(bases))
    assert info["is_success"]  # the planner's exploratory path, replayed exactly


def test_redraw_keeps_shapes_that_lift_from_the_placement():
    env = PlannerResidual(_lift_env(), redraw=True)
    assert env.policy.fallbacks is False
    env.reset(seed=STUCK - 12)  # the first held-out shape gets stuck as well
    assert env.policy.plan.success and not env.policy.on_fallback
    first = env.unwrapped.scene.object.vertices_B.copy()
    plain = _lift_env()
    plain.reset(seed=STUCK - 12)
    assert not np.array_equal(first, plain.unwrapped.scene.object.vertices_B)  # redrawn


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"scale": 0.0}, "scale must be in \\(0, 1\\], got 0.0"),
        ({"scale": 1.5}, "scale must be in \\(0, 1\\], got 1.5"),
        ({"scale": "big"}, "scale must be in \\(0, 1\\], got 'big'"),
        ({"scale": True}, "scale must be in \\(0, 1\\], got True"),
        ({"scale": float("nan")}, "scale must be in \\(0, 1\\], got nan"),
        ({"correction_cost": -0.1}, "correction_cost must be a finite number >= 0, got -0.1"),
        ({"correction_cost": float("inf")}, "correction_cost must be .* got inf"),
        ({"correction_cost": "x"}, "correction_cost must be .* got 'x'"),
    ],
)
def test_bad_arguments_are_named(kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        PlannerResidual(_lift_env(), **kwargs)


def test_an_env_without_palm_control_is_refused():
    with pytest.raises(ValueError, match="palm_control=True"):
        PlannerResidual(gym.make("FrictionlessGrasp-v0"))


@pytest.mark.parametrize(
    "bad", [np.zeros(4), np.array([0, 0, np.nan, 0, 0]), np.full(5, np.inf), "go"], ids=str
)
def test_a_bad_correction_is_named_and_the_env_stays_usable(bad):
    env = PlannerResidual(_lift_env())
    obs, _ = env.reset(seed=LIFTS)
    hand = env.unwrapped.state.hand.copy()
    with pytest.raises(ValueError, match=r"action \(the correction\) must be (5 real|finite)"):
        env.step(bad)
    np.testing.assert_array_equal(env.unwrapped.state.hand, hand)
    np.testing.assert_array_equal(obs[-5:], env._base)
    obs, _, _, _, info = env.step(np.zeros(5, np.float32))
    assert np.isfinite(obs).all() and "sim_error" not in info


def test_the_residual_config_names_the_wrapper_and_evaluation_plays_it():
    env_id, conf = "FrictionlessGraspLift-v0", ROOT / "configs" / "ppo_residual.yml"
    entry = train_ppo.prepare(env_id, conf)
    assert planner_wrapper(entry) == (PlannerResidual, {"scale": 0.25, "redraw": False})
    plain = train_ppo.prepare(env_id, ROOT / "configs" / "ppo.yml")
    assert planner_wrapper(plain) is None
    assert shipped_name(conf, env_id) == "lift_residual"
    assert shipped_name("configs/ppo.yml", env_id) == "lift_palm"
    with pytest.raises(ValueError, match=r"no shipped model of configs/ppo_residual\.yml for 'F"):
        shipped_name(conf, "FrictionlessGrasp-v0")
    spec = PolicySpec("ppo_x", "ppo", {"palm_control": True}, None, planner_wrapper(entry))
    env = make_env(spec, LIFT_KWARGS, 200)
    assert isinstance(env, PlannerResidual) and not env.redraw and env.policy.fallbacks


@pytest.mark.parametrize("seed", [LIFTS, STUCK])
def test_the_grip_agents_correction_waits_for_the_planner_to_finish(seed):
    planner = _lift_env()
    obs, info = planner.reset(seed=seed)
    policy = ScriptedPolicy(planner)
    policy.reset(obs, info)
    assert policy.on_fallback == (seed == STUCK)  # the fallback's path is waited for too
    planned = []
    while not (policy.done and planned and not planned[-1].any()):
        planned.append(policy.act(obs))
        obs, *_ = planner.step(planned[-1])
    planned.pop()  # the first zero action: the plan is done
    assert len(planned) > 10
    sent = _Sent(_lift_env())
    env = PlannerGrip(sent)
    env.reset(seed=seed)
    correction = np.full(5, 0.5, np.float32)
    for _ in range(len(planned) + 3):
        env.step(correction)
    np.testing.assert_array_equal(np.array(sent.sent[: len(planned)]), np.array(planned))
    np.testing.assert_allclose(np.array(sent.sent[len(planned) :]), 0.125)  # 0.25 x 0.5


def _failing_reset(monkeypatch, fail_first: int):
    """Make the planner's first ``fail_first`` resets fail as a move the simulator cannot
    make does (the shape's planning raises ``WorkLimitError``)."""
    calls = {"n": 0}
    original = ScriptedPolicy.reset

    def reset(self, obs=None, info=None):
        calls["n"] += 1
        if calls["n"] <= fail_first:
            raise WorkLimitError("the move needs more than 5000 pose solves")
        return original(self, obs, info)

    monkeypatch.setattr(ScriptedPolicy, "reset", reset)
    return calls


def test_a_planning_failure_is_redrawn_in_training_and_raised_otherwise(monkeypatch):
    calls = _failing_reset(monkeypatch, 2)
    env = PlannerResidual(_lift_env(), redraw=True)
    obs, _ = env.reset(seed=LIFTS)
    assert calls["n"] >= 3 and env.policy.plan.success and obs[-5:].any()
    calls = _failing_reset(monkeypatch, 1)
    with pytest.raises(WorkLimitError, match="5000 pose solves"):
        PlannerResidual(_lift_env()).reset(seed=LIFTS)


def test_a_failed_replan_in_training_leaves_the_correction_in_charge(monkeypatch):
    sent = _Sent(_lift_env())
    env = PlannerGrip(sent, redraw=True)
    env.reset(seed=LIFTS)

    def act(obs=None):
        raise WorkLimitError("the move needs more than 5000 pose solves")

    monkeypatch.setattr(env.policy, "act", act)
    _, _, _, _, info = env.step(np.ones(5, np.float32))
    assert info["planner_error"] == "WorkLimitError: the move needs more than 5000 pose solves"
    obs, _, _, _, info = env.step(np.ones(5, np.float32))
    assert not obs[-5:].any() and "planner_error" not in info
    np.testing.assert_array_equal(sent.sent[-1], np.full(5, 0.25, np.float32))
    plain = PlannerResidual(_lift_env())
    plain.reset(seed=LIFTS)
    monkeypatch.setattr(plain.policy, "act", act)
    with pytest.raises(WorkLimitError):
        plain.step(np.zeros(5, np.float32))


def test_a_palm_only_correction_after_the_plan_turns_the_grasp_as_one_body():
    sent = _Sent(_lift_env())
    env = PlannerGrip(sent, scale=1.0, palm_only=True)
    assert env.action_space.shape == (3,)
    obs, _ = env.reset(seed=LIFTS)
    turn = np.array([0.0, 0.0, 1.0], np.float32)
    while not (env.policy.done and not obs[-5:].any()):  # the planner holds still
        obs, _, _, _, info = env.step(turn)  # ignored while the planner plays
    assert info["is_success"]
    base = env.unwrapped
    state = base.state
    start_hand, start_pose = state.hand.copy(), state.object_pose.copy()
    for _ in range(5):
        *_, info = env.step(turn)
        assert info["is_success"]
    np.testing.assert_array_equal(sent.sent[-1], [0, 0, 0, 0, 1])
    state = base.state
    dtheta = 5 * base.max_palm_step[2]
    np.testing.assert_allclose(state.hand - start_hand, [0, 0, dtheta, 0, 0], atol=1e-12)
    # the object turned with the palm about the palm's origin: rotate its start pose by hand
    c, s = np.cos(dtheta), np.sin(dtheta)
    rel = start_pose[:2] - start_hand[:2]
    turned = [c * rel[0] - s * rel[1], s * rel[0] + c * rel[1]]
    expected = np.r_[start_hand[:2] + turned, start_pose[2] + dtheta]
    np.testing.assert_allclose(state.object_pose, expected, atol=1e-9)
    with pytest.raises(ValueError, match="correction"):
        env.step(np.zeros(5, np.float32))
    env.step(turn)  # still usable


def _grip_W(state) -> float:
    """y*/W of a state, computed from it, as the residual's observation caps it (10)."""
    closed = len(state.contacts) >= 4 and is_form_closure(state)
    grip = grip_objective(state) / state.scene.object_weight if closed else math.inf
    return min(grip, 10.0)


def test_last_step_observes_the_action_sent_and_the_grip_before_it():
    sent = _Sent(_lift_env())
    env = PlannerGrip(sent, scale=1.0, palm_only=True, last_step=True)
    assert env.observation_space.shape[0] == env.env.observation_space.shape[0] + 11
    obs, _ = env.reset(seed=LIFTS)
    assert not obs[-6:-1].any()
    before = env.unwrapped.state
    for t in range(60):
        obs, *_ = env.step(np.array([0.0, 0.0, 1.0 if t % 2 else -0.5], np.float32))
        np.testing.assert_array_equal(obs[-6:-1], sent.sent[-1])
        # y*/W of the state before the step, computed again from that state
        assert obs[-1] == pytest.approx(_grip_W(before), rel=1e-6)
        before = env.unwrapped.state
    assert obs[-1] < 10.0  # the planner has closed on the object by then


def test_the_grip_config_plays_after_the_plan_and_ships_apart_from_the_residual():
    env_id, conf = "FrictionlessGraspLift-v0", ROOT / "configs" / "ppo_grip.yml"
    entry = train_ppo.prepare(env_id, conf)
    wrapper = planner_wrapper(entry)
    assert wrapper == (
        PlannerGrip,
        {
            "scale": 1.0,
            "redraw": False,
            "palm_only": True,
            "last_step": True,
            "grip_shaping": 50.0,
            "probe_turns": True,
        },
    )
    assert entry["env_kwargs"]["reward_lift_weight"] == 0.0
    assert shipped_name(conf, env_id) == "lift_grip"  # not lift_residual
    env = make_env(
        PolicySpec("ppo_x", "ppo", {"palm_control": True}, None, wrapper), LIFT_KWARGS, 200
    )
    assert env.action_space.shape == (3,) and env.policy.fallbacks


def test_grip_shaping_credits_each_acting_step_with_the_fall_of_the_grip():
    inner = _Rewards(_lift_env())
    env = PlannerGrip(inner, scale=1.0, palm_only=True, grip_shaping=50.0)
    obs, _ = env.reset(seed=LIFTS)
    acted, shapings = 0, []
    for t in range(80):
        before, played = env.unwrapped.state, env.policy.done and not obs[-5:].any()
        obs, reward, *_, info = env.step(np.array([0.0, 0.0, -1.0 if t % 3 else 1.0], np.float32))
        shaping = 50.0 * (_grip_W(before) - _grip_W(env.unwrapped.state)) if played else 0.0
        acted += played
        shapings.append(shaping)
        assert reward == pytest.approx(inner.rewards[-1] + shaping, rel=1e-6, abs=1e-9)
        assert info.get("reward_grip_shaping", 0.0) == pytest.approx(shaping, rel=1e-6, abs=1e-9)
    assert acted > 20 and max(map(abs, shapings)) > 1e-3  # the turns changed the grip
    for bad in (-1.0, math.nan, True, "1"):
        with pytest.raises(ValueError, match="grip_shaping must be a finite number >= 0"):
            PlannerGrip(_lift_env(), grip_shaping=bad)


def _probing_env() -> PlannerGrip:
    return PlannerGrip(_lift_env(), scale=1.0, palm_only=True, probe_turns=True)


def test_turn_probes_observe_what_a_full_turn_each_way_then_does():
    env = _probing_env()
    assert env.observation_space.shape[0] == env.env.observation_space.shape[0] + 7
    obs, _ = env.reset(seed=LIFTS)
    actions, checked = [], 0
    while checked < 3:
        if not (env.policy.done and not obs[-7:-2].any()):  # the planner still plays
            assert not obs[-2:].any()
        elif len(actions) % 4 == 0:
            # replay the episode in a fresh env, then turn each way with a real step
            for sign, probe in zip((1.0, -1.0), obs[-2:], strict=True):
                replay = _probing_env()
                replay.reset(seed=LIFTS)
                for action in actions:
                    replay.step(action)
                before = _grip_W(replay.unwrapped.state)
                replay.step(np.array([0.0, 0.0, sign], np.float32))
                assert probe == pytest.approx(_grip_W(replay.unwrapped.state) - before, abs=1e-6)
            checked += 1
        actions.append(np.array([0.0, 0.0, 0.3 if len(actions) % 3 else -0.2], np.float32))
        obs, *_ = env.step(actions[-1])


def test_turning_where_the_probes_say_lightens_the_planners_grip():
    env = _probing_env()
    obs, _ = env.reset(seed=LIFTS)
    planner = None
    for _ in range(150):
        turn = 0.0
        if env.policy.done and not obs[-7:-2].any():
            planner = planner or _grip_W(env.unwrapped.state)
            if min(obs[-2:]) < 0:
                turn = 1.0 if obs[-2] <= obs[-1] else -1.0
        obs, *_, info = env.step(np.array([0.0, 0.0, turn], np.float32))
    assert info["is_success"]
    assert _grip_W(env.unwrapped.state) < planner - 0.02  # 1.03 W: the planner's
