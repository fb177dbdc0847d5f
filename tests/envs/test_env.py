"""FrictionlessGrasp-v0: API conformance, determinism, vectorisation, validation, rewards."""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import grasp_env
from grasp_env.core import geometry as geo
from grasp_env.envs import ENV_ID, MAX_EPISODE_STEPS, REWARD_THRESHOLD, VECTOR_ENTRY_POINT, shapes
from grasp_env.envs import frictionless_grasp as fg_module
from grasp_env.envs.episode import Episode, episode_constants
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.envs.shapes import DEFAULT_SHAPE_RANGES, hand_setup, random_convex_polygon
from grasp_env.kernel.observation import observation_bounds
from grasp_env.planning import close_until_touch

PALM_CONTROL = [False, True]
PALM_IDS = ["fingers-only", "palm-control"]
REWARD_KEYS = [
    "reward_form_closure", "reward_hold", "reward_grip", "reward_lift", "reward_drop",
    "reward_ctrl",
]  # fmt: skip
#: The info keys that docs/conventions.md ("The environment") guarantees at reset and step.
DOCUMENTED_INFO_KEYS = {
    "object_pose",
    "palm_pose",
    "finger_angles",
    "contacts",
    "form_closure",
    "grip_force",
    "jammed",
    "dropped",
}


def _same(a, b) -> bool:
    """Exact equality of nested obs/info values (NaN equal to NaN)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray | float | np.floating):
        return np.array_equal(a, b, equal_nan=True)
    return a == b


def _rollout(env, seed: int, steps: int, action_seed: int = 0, reset_options=None):
    rng = np.random.default_rng(action_seed)
    obs, info = env.reset(seed=seed, options=reset_options)
    out = [(obs, 0.0, False, False, info)]
    for _ in range(steps):
        action = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        out.append(env.step(action))
        if out[-1][2] or out[-1][3]:
            obs, info = env.reset()
            out.append((obs, 0.0, False, False, info))
    return out


def _close_until(env, predicate, max_steps: int = 40):
    for _ in range(max_steps):
        obs, reward, terminated, truncated, info = env.step(np.ones(env.action_space.shape))
        if predicate(info) or terminated:
            return obs, reward, terminated, truncated, info
    raise AssertionError("condition not reached")


# ---------------------------------------------------------------------- registration, checkers
def test_registered_with_string_entry_points_and_its_own_time_limit():
    """``gymnasium.make`` gives the env itself (no wrapper to restore after a refused call);
    it truncates its episodes at the registered ``time_limit``, 200 steps."""
    spec = gym.spec(ENV_ID)
    assert isinstance(spec.entry_point, str) and spec.vector_entry_point == VECTOR_ENTRY_POINT
    assert spec.max_episode_steps is None and spec.kwargs["time_limit"] == MAX_EPISODE_STEPS == 200
    assert not spec.additional_wrappers and not spec.order_enforce and spec.disable_env_checker
    env = gym.make("grasp_env:FrictionlessGrasp-v0", scene="square")
    assert env.unwrapped.scenes[0].name == "square"
    assert type(env) is FrictionlessGraspEnv
    env.reset(seed=0)
    ends = []
    for _ in range(MAX_EPISODE_STEPS):
        _, _, terminated, truncated, _ = env.step(np.zeros(2))  # the hand stays where it is
        ends.append((terminated, truncated))
    assert ends[:-1] == [(False, False)] * (MAX_EPISODE_STEPS - 1)
    assert ends[-1] == (False, True)
    env.close()


#: Every registered id and the ``gymnasium.make`` kwargs its spec holds.
REGISTERED = {
    "FrictionlessGrasp-v0": {"time_limit": 200},
    "FrictionlessGraspRandomShapes-v0": {
        "scene": "fig13",
        "shape_randomizer": True,
        "palm_control": True,
        "start": "scene",
        "time_limit": 200,
    },
    "FrictionlessGraspLift-v0": {
        "scene": "fig13",
        "shape_randomizer": True,
        "palm_control": True,
        "start": "placement",
        "hand_features": True,
        "time_limit": 200,
    },
}


def test_every_set_up_has_its_id():
    from grasp_env.envs import ENV_KWARGS, RANDOM_SHAPES_ENV_ID

    assert {k: dict(v) for k, v in ENV_KWARGS.items()} == REGISTERED
    assert RANDOM_SHAPES_ENV_ID == "FrictionlessGraspRandomShapes-v0"
    # The paper's id keeps the env's defaults: fig13, palm fixed, start at the scene.
    defaults = inspect.signature(FrictionlessGraspEnv).parameters
    assert defaults["scene"].default == "fig13" and defaults["palm_control"].default is False
    assert defaults["start"].default == "scene" and defaults["shape_randomizer"].default is None


@pytest.mark.parametrize("env_id", REGISTERED, ids=REGISTERED)
def test_registered_ids_share_entry_point_wrappers_and_threshold(env_id):
    spec = gym.spec(env_id)
    main = gym.spec(ENV_ID)
    assert isinstance(spec.entry_point, str) and spec.entry_point == main.entry_point
    assert spec.kwargs == REGISTERED[env_id]
    assert spec.vector_entry_point == main.vector_entry_point == VECTOR_ENTRY_POINT
    assert spec.max_episode_steps is None and spec.reward_threshold == REWARD_THRESHOLD
    assert not spec.additional_wrappers
    env = gym.make(f"grasp_env:{env_id}")
    assert type(env) is FrictionlessGraspEnv and env.spec.kwargs == REGISTERED[env_id]
    unwrapped = env.unwrapped
    palm = REGISTERED[env_id].get("palm_control", False)
    assert unwrapped.action_space.shape == ((5,) if palm else (2,))
    assert (unwrapped.shape_ranges is not None) == ("shape_randomizer" in REGISTERED[env_id])
    assert unwrapped.scenes[0].name == "fig13"
    assert unwrapped.start == REGISTERED[env_id].get("start", "scene")
    assert unwrapped.hand_features == REGISTERED[env_id].get("hand_features", False)
    env.close()


@pytest.mark.parametrize("env_id", REGISTERED, ids=REGISTERED)
def test_registered_ids_pass_gymnasium_check_env(env_id):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)
    env.close()


def test_make_kwargs_override_the_registered_ones():
    env = gym.make("FrictionlessGraspRandomShapes-v0", palm_control=False, reward_grip_weight=1.0)
    assert env.action_space.shape == (2,) and env.unwrapped.shape_ranges is not None
    assert env.unwrapped.reward_weights["grip"] == 1.0
    env.close()
    # Different random shapes on different seeds, the same on the same seed.
    env = gym.make("FrictionlessGraspRandomShapes-v0")
    vertices = slice(13, 13 + 2 * 12)
    first, second = (env.reset(seed=s)[0][vertices] for s in (0, 1))
    assert not np.array_equal(first, second)
    assert np.array_equal(env.reset(seed=0)[0][vertices], first)
    env.close()


CHECK_ENV_CASES = {
    "fingers-only": {},
    "palm-control": {"palm_control": True},
    "rgb-array": {"render_mode": "rgb_array", "render_width": 64, "render_height": 48},
    "randomizer-random-start": {"shape_randomizer": True, "start": "random", "palm_control": True},
}


@pytest.mark.parametrize("kwargs", CHECK_ENV_CASES.values(), ids=CHECK_ENV_CASES.keys())
def test_gymnasium_check_env(kwargs):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(ENV_ID, **kwargs).unwrapped  # made: the render check needs env.spec
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check="render_mode" not in kwargs)
    env.close()


@pytest.mark.parametrize("palm_control", PALM_CONTROL, ids=PALM_IDS)
def test_sb3_check_env(palm_control):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_checker import check_env

    env = FrictionlessGraspEnv(palm_control=palm_control)
    env.action_space.seed(0)  # check_env steps with sampled actions: keep them reproducible
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, warn=True)
    env.close()


@pytest.mark.parametrize("palm_control", PALM_CONTROL, ids=PALM_IDS)
def test_spaces(palm_control):
    env = FrictionlessGraspEnv(palm_control=palm_control)
    assert env.action_space == gym.spaces.Box(-1, 1, (5 if palm_control else 2,), np.float32)
    space = env.observation_space
    assert space.dtype == np.float32 and space.shape == (24 + 3 * 12,)
    assert np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
    assert np.all(space.low < space.high)


def test_reward_threshold_is_the_form_closure_bonus():
    assert gym.spec(ENV_ID).reward_threshold == REWARD_THRESHOLD == 10.0
    assert gym.make(ENV_ID).spec.reward_threshold == REWARD_THRESHOLD
    default = inspect.signature(FrictionlessGraspEnv).parameters["reward_form_closure_weight"]
    assert default.default == REWARD_THRESHOLD
    assert "reward_threshold" in FrictionlessGraspEnv.__doc__


def _episode_return(env, actions, steps: int) -> tuple[float, dict]:
    total, info = 0.0, {}
    for k in range(steps):
        _, reward, terminated, truncated, info = env.step(actions(k, info))
        total += reward
        if terminated or truncated:
            break
    return total, info


def test_reward_threshold_separates_grasps_from_failures():
    env = gym.make(ENV_ID, start="preliftoff")
    # A grasp, held: squeeze until form closure off the support, then hold still.
    env.reset(seed=0)
    held = {"done": False}

    def squeeze_then_hold(k, info):
        held["done"] |= bool(info.get("is_success"))
        return np.zeros(2) if held["done"] else np.ones(2)

    total, info = _episode_return(env, squeeze_then_hold, 20)
    assert info["is_success"] and total >= REWARD_THRESHOLD
    # A grasp lost at once: the drop penalty cancels the bonus.
    env.reset(seed=0)
    total, info = _episode_return(env, lambda k, info: np.ones(2) if k < 8 else -np.ones(2), 60)
    assert info["dropped"] and total < REWARD_THRESHOLD
    # Random actions over a whole episode (200 steps).
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    env.action_space.seed(0)
    total, info = _episode_return(env, lambda k, info: env.action_space.sample(), 10_000)
    assert not info["is_success"] and total < REWARD_THRESHOLD


# ---------------------------------------------------------------------- public accessors
def test_accessors_before_reset_are_none():
    env = FrictionlessGraspEnv()
    assert env.state is None and env.simulator is None and env.scene is None
    with pytest.raises(RuntimeError, match=r"call reset\(\) before simulate_action"):
        env.simulate_action(None, np.zeros(2))


@pytest.mark.parametrize("palm_control", PALM_CONTROL, ids=PALM_IDS)
def test_accessors_give_the_episode_state_simulator_and_scene(palm_control):
    env = gym.make(ENV_ID, scene=["fig13", "square"], palm_control=palm_control)
    base = env.unwrapped
    _, info = env.reset(seed=0, options={"scene": "hexagon"})
    assert isinstance(base.state, grasp_env.State)
    assert isinstance(base.simulator, grasp_env.Simulator)
    assert isinstance(base.scene, grasp_env.Scene)
    assert base.scene.name == "hexagon"
    assert base.state.scene is base.scene and base.simulator.scene is base.scene
    np.testing.assert_array_equal(base.state.object_pose, info["object_pose"])
    before = base.state
    _, _, _, _, info = env.step(np.ones(env.action_space.shape))
    assert base.state is not before  # a new immutable state every step
    np.testing.assert_array_equal(base.state.finger_angles, info["finger_angles"])
    for name in ("state", "simulator", "scene"):
        with pytest.raises(AttributeError):
            setattr(base, name, None)
    assert env.get_wrapper_attr("state") is base.state


def test_simulate_action_checks_and_clips_like_step():
    env = FrictionlessGraspEnv(start="preliftoff")
    env.reset(seed=0)
    state = env.state
    clipped = env.simulate_action(state, [1.0, 1.0])
    np.testing.assert_array_equal(env.simulate_action(state, [7.0, 3.0]).hand, clipped.hand)
    assert env.state is state
    with pytest.raises(ValueError, match="action"):
        env.simulate_action(state, [math.nan, 0.0])
    with pytest.raises(ValueError, match="action"):
        env.simulate_action(state, np.zeros(5))
    with pytest.raises(TypeError, match=r"state must be a grasp_env\.State"):
        env.simulate_action(state.hand, np.zeros(2))
    with pytest.raises(ValueError, match=r"hand must be finite.*nan"):  # built by hand
        dataclasses.replace(state, hand=np.array([0.0, 0.5, math.nan, -1.0, -1.0]))
    bad = dataclasses.replace(state, hand=state.hand.copy())
    with pytest.raises(ValueError, match="read-only"):
        bad.hand[2] = math.nan  # a state is a snapshot


def test_accessors_are_documented():
    doc = FrictionlessGraspEnv.__doc__
    for name in ("state", "simulator", "scene"):
        assert f":attr:`{name}`" in doc and getattr(FrictionlessGraspEnv, name).__doc__
    assert "simulate_action(state, action)" in doc
    assert "Raises:" in FrictionlessGraspEnv.simulate_action.__doc__


# ---------------------------------------------------------------------- determinism, pickling
def test_seeded_rollout_is_reproducible():
    runs = [_rollout(FrictionlessGraspEnv(), seed=3, steps=200) for _ in range(2)]
    assert len(runs[0]) == len(runs[1])
    for a, b in zip(*runs, strict=True):
        assert _same(a, b)
    # The rollout did something: the fingers touched the object at some step.
    assert any(c["body"].startswith("finger") for step in runs[0] for c in step[-1]["contacts"])


def test_episodes_from_a_kept_start_begin_as_a_fresh_analysis_would():
    """A reset to a start the env keeps (here a pool entry) copies the first episode from it
    instead of analysing the start again: each such episode must be, array for array, the
    one built afresh, whatever the earlier episodes from that start did."""
    env = gym.make("FrictionlessGraspLift-v0", shape_pool=3, time_limit=12).unwrapped
    rng = np.random.default_rng(0)
    bounds = env._settings, env._obs_low, env._obs_high
    env.reset(seed=0)
    for _ in range(10):
        ended = False
        while not ended:
            *_, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 5))
            ended = terminated or truncated
        obs, _ = env.reset()
        got = env._episode
        consts = episode_constants(
            got.state.scene, got.state, env.max_finger_step, env.max_palm_step,
            got.sim.model.rho,
        )  # fmt: skip
        fresh = Episode(got.sim, got.state, consts, env._settings, len(env._obs_low))
        np.testing.assert_array_equal(obs, fresh.observation(*bounds))
        for name in ("consts", "q", "h", "keys", "rows", "an", "ep", "obs"):
            np.testing.assert_array_equal(getattr(got, name), getattr(fresh, name), name)
    assert len(env._episodes) == 3  # 11 episodes from 3 starts: the copies were used


@pytest.mark.parametrize("palm_control", [False, True])
def test_simulate_action_is_what_step_does(palm_control):
    # The model planners use: the same state to the last bit, and the env left untouched.
    env = FrictionlessGraspEnv(start="preliftoff", palm_control=palm_control)
    env.reset(seed=2)
    rng = np.random.default_rng(2)
    for _ in range(20):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        before = env.state
        predicted = env.simulate_action(before, action)
        assert env.state is before
        env.step(action)
        np.testing.assert_array_equal(predicted.hand, env.state.hand)
        np.testing.assert_array_equal(predicted.object_pose, env.state.object_pose)


def test_pickle_round_trip_mid_episode():
    env = FrictionlessGraspEnv(start="preliftoff")
    env.reset(seed=1)
    rng = np.random.default_rng(1)
    for _ in range(5):
        env.step(rng.uniform(-1, 1, 2))
    copy = pickle.loads(pickle.dumps(env))
    for _ in range(5):
        action = rng.uniform(-1, 1, 2)
        assert _same(env.step(action), copy.step(action))


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec_matches_single_envs(mode):
    kwargs = {"scene": ["fig13", "square", "triangle"]}
    vector_kwargs = {"context": "spawn"} if mode == "async" else {}
    venv = gym.make_vec(
        ENV_ID, num_envs=2, vectorization_mode=mode, vector_kwargs=vector_kwargs, **kwargs
    )
    singles = [gym.make(ENV_ID, **kwargs) for _ in range(2)]
    try:
        obs, _ = venv.reset(seed=10)
        for i, env in enumerate(singles):
            assert np.array_equal(obs[i], env.reset(seed=10 + i)[0])
        rng = np.random.default_rng(0)
        for _ in range(4):
            actions = rng.uniform(-1, 1, (2, 2)).astype(np.float32)
            obs, rewards, *_ = venv.step(actions)
            for i, env in enumerate(singles):
                o, r, *_ = env.step(actions[i])
                assert np.array_equal(obs[i], o) and rewards[i] == r
    finally:
        venv.close()
        for env in singles:
            env.close()


def test_sb3_subproc_vec_env():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    # fork starts fast; spawned workers are covered by test_make_vec_matches_single_envs.
    venv = make_vec_env(
        f"grasp_env:{ENV_ID}",
        n_envs=2,
        seed=0,
        vec_env_cls=SubprocVecEnv,
        vec_env_kwargs={"start_method": "fork"},
    )
    try:
        obs = venv.reset()
        assert obs.shape == (2, 60)
        for _ in range(3):
            obs, rewards, _, infos = venv.step(np.zeros((2, 2), dtype=np.float32))
        assert obs.shape == (2, 60) and rewards.shape == (2,) and len(infos) == 2
        assert all("is_success" in info for info in infos)
    finally:
        venv.close()


# ---------------------------------------------------------------------- reset and starts
def test_info_keys_on_reset_and_step():
    env = FrictionlessGraspEnv()
    _, reset_info = env.reset(seed=0)
    for info in (reset_info, env.step(np.zeros(2))[-1]):
        assert DOCUMENTED_INFO_KEYS | {"events", "is_success", *REWARD_KEYS} <= info.keys()
        assert [k for k in info if k.startswith("reward_")] == REWARD_KEYS  # one order
        for key in ("object_pose", "palm_pose", "finger_angles"):
            assert isinstance(info[key], np.ndarray)
        assert all(
            {"body", "kind", "point", "normal", "force"} <= c.keys() for c in info["contacts"]
        )
        assert type(info["grip_force"]) is float
        assert math.isfinite(info["grip_force"]) == info["form_closure"]


def test_grip_force_is_a_plain_float_inf_outside_form_closure():
    env = FrictionlessGraspEnv(start="preliftoff")
    _, info = env.reset(seed=0)
    assert type(info["grip_force"]) is float and info["grip_force"] == math.inf
    assert info["grip_force"] == info["grip_force"]  # compares equal to itself (check_env)
    _, _, _, _, info = _close_until(env, lambda i: i["form_closure"])
    assert type(info["grip_force"]) is float and math.isfinite(info["grip_force"])
    assert not hasattr(fg_module, "_NaN") and not hasattr(fg_module, "NAN")
    assert "``inf``" in FrictionlessGraspEnv.__doc__.split("grip_force")[1][:120]


def test_grip_force_vectorizes_as_floats():
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync")
    _, info = envs.reset(seed=0)
    assert info["grip_force"].dtype == np.float64
    assert np.all(info["grip_force"] == math.inf)
    envs.close()


def test_reset_options_start_from_given_configuration():
    env = FrictionlessGraspEnv()
    palm, fingers = (0.05, 0.8, 0.1), (-1.4, -1.8)
    _, info = env.reset(seed=0, options={"scene": "square", "palm": palm, "fingers": fingers})
    assert env.scene.name == "square"
    assert np.allclose(info["palm_pose"], palm) and np.allclose(info["finger_angles"], fingers)
    # Missing parts come from the scene.
    _, info = env.reset(options={"fingers": fingers})
    scene = grasp_env.load_scene("fig13")
    assert np.allclose(info["palm_pose"], scene.palm.pose)
    assert np.allclose(info["finger_angles"], fingers)


def test_object_pose_option_drops_an_unheld_object_to_its_rest():
    # Released tilted above its scene placement, clear of the hand, the fig13 object falls
    # back onto the face it rested on: the scene's start pose, its two lowest vertices on
    # the support (the object's vertices as the scene file gives them).
    scene = grasp_env.load_scene("fig13")
    env = FrictionlessGraspEnv()
    start = scene.object.start_pose
    _, info = env.reset(seed=0, options={"object_pose": start + np.array([0.0, 0.3, 0.15])})
    assert [e.kind for e in env.state.events] == ["fall_start", "fall_end"]
    pose = env.state.object_pose
    assert np.allclose(pose, start, atol=1e-7)
    heights = np.sort(geo.transform(pose, scene.object.vertices_B)[:, 1])
    assert np.allclose(heights[:2], 0.0, atol=1e-7) and heights[2] > 0.05
    assert np.allclose(info["palm_pose"], scene.palm.pose)


def test_object_pose_option_restarts_a_held_state():
    # A state along the planner's trajectory, the object held off the support, is a start
    # that stays where it is: the same pose, in form closure.
    plan = grasp_env.planning.plan_grasp("fig13")
    held = plan.steps[-1].state
    assert plan.success and not held.on_support
    options = {"palm": held.hand[:3], "fingers": held.hand[3:], "object_pose": held.object_pose}
    env = FrictionlessGraspEnv()
    _, info = env.reset(seed=0, options=options)
    assert info["is_success"] and not env.state.on_support
    assert np.allclose(env.state.object_pose, held.object_pose, atol=1e-9)
    assert np.allclose(env.state.hand, held.hand)
    # The batched env gives every sub-env the same start.
    envs = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point")
    _, infos = envs.reset(seed=0, options=options)
    assert infos["is_success"].all()
    for i in range(2):
        assert np.allclose(envs.unwrapped.sub_env(i).state.object_pose, held.object_pose)
    envs.close()


@pytest.mark.parametrize("scene", ["fig13", "hexagon", "offset_pentagon"])
def test_preliftoff_start_touches_with_both_fingers(scene):
    env = FrictionlessGraspEnv(scene=scene, start="preliftoff")
    _, info = env.reset(seed=0)
    bodies = {c["body"] for c in info["contacts"]}
    assert info["jammed"] or {"finger1", "finger2"} <= bodies
    assert info["palm_pose"][2] == 0.0
    # Centred over the object at the scene placement, the longer finger just clear.
    s = grasp_env.load_scene(scene)
    assert info["palm_pose"][0] == pytest.approx(s.object.start_pose[0])
    assert info["palm_pose"][1] == pytest.approx(max(f.length for f in s.fingers) + 0.01)


@pytest.mark.parametrize("scene", ["fig13", "triangle"])
def test_preliftoff_closing_does_not_depend_on_the_step(scene):
    # The first touch is located from the simulator's events, so the step size only changes
    # the cost: coarse and fine closing reach the same configuration.
    sim = grasp_env.Simulator(scene)
    start = sim.settle(sim.scene.object.start_pose, hand_setup(sim.scene))
    fine, coarse = (close_until_touch(sim, start, step) for step in (0.03, 0.25))
    assert np.allclose(fine.hand, coarse.hand, atol=1e-9)
    assert np.allclose(fine.object_pose, coarse.object_pose, atol=1e-9)


def test_random_start_is_clear_and_seeded():
    env = FrictionlessGraspEnv(start="random")
    starts = [env.reset(seed=s)[1]["finger_angles"] for s in (0, 1, 0)]
    assert np.array_equal(starts[0], starts[2]) and not np.array_equal(starts[0], starts[1])
    for _ in range(3):
        env.reset()
        state = env.state
        obj = geo.transform(state.object_pose, state.scene.object.vertices_B)
        for poly in grasp_env.core.kinematics.hand_polygons_W(state.scene, state.hand):
            assert geo.penetration_depth(poly, obj) <= 1e-9
            assert poly[:, 1].min() >= -1e-9


# ---------------------------------------------------------------------- validation
BAD_KWARGS = [
    ({"scene": "no_such_scene"}, ValueError, "no_such_scene"),
    ({"scene": 3}, TypeError, "scene"),
    ({"scene": []}, ValueError, "scene"),
    ({"palm_control": "yes"}, TypeError, "palm_control"),
    ({"max_finger_step": -0.1}, ValueError, "max_finger_step"),
    ({"max_finger_step": float("nan")}, ValueError, "max_finger_step"),
    ({"max_palm_step": (0.1, 0.1)}, ValueError, "max_palm_step"),
    ({"start": "middle"}, ValueError, "start"),
    ({"reward_drop_weight": -1.0}, ValueError, "reward_drop_weight"),
    ({"reward_grip_weight": "big"}, TypeError, "reward_grip_weight"),
    ({"gamma": 1.5}, ValueError, "gamma"),
    ({"contact_tol": 0.0}, ValueError, "contact_tol"),
    ({"max_vertices": 4}, ValueError, "max_vertices"),
    ({"max_vertices": 12.0}, TypeError, "max_vertices"),
    ({"render_mode": "ascii"}, ValueError, "render_mode"),
    ({"shape_randomizer": {"sides": (3, 5)}}, ValueError, "sides"),
    ({"shape_randomizer": {"size": (0.5, 0.1)}}, ValueError, "size"),
    ({"shape_randomizer": {"vertices": (2, 5)}}, ValueError, "vertices"),
    ({"shape_randomizer": "on"}, TypeError, "shape_randomizer"),
]


@pytest.mark.parametrize(
    ("kwargs", "exc", "name"), BAD_KWARGS, ids=[f"{next(iter(k))}-{n}" for k, _, n in BAD_KWARGS]
)
def test_bad_kwargs_are_refused(kwargs, exc, name):
    with pytest.raises(exc, match=name):
        FrictionlessGraspEnv(**kwargs)


BAD_OPTIONS = [
    ({"palm": (0.0, 0.8)}, ValueError, "palm"),
    ({"palm": (0.0, 0.2, 0.0)}, ValueError, "overlaps the object"),
    ({"palm": (0.0, 0.5, 0.0)}, ValueError, "support"),
    ({"palm": (0.0, float("inf"), 0.0)}, ValueError, "palm"),
    ({"fingers": (-1.0, 0.5)}, ValueError, "fingers"),
    ({"fingers": (-0.6, -2.5)}, ValueError, "overlaps"),
    ({"hand": (0, 0, 0)}, ValueError, "hand"),
    ({"scene": "nowhere"}, ValueError, "nowhere"),
    ("fig13", TypeError, "options"),
]


@pytest.mark.parametrize(
    ("options", "exc", "match"),
    BAD_OPTIONS,
    ids=["palm-size", "palm-in-object", "palm-in-support", "palm-inf", "fingers-limits",
         "fingers-in-object", "unknown-key", "unknown-scene", "not-a-dict"],
)  # fmt: skip
def test_bad_reset_options_are_refused_and_env_keeps_working(options, exc, match):
    env = FrictionlessGraspEnv()
    env.reset(seed=0)
    with pytest.raises(exc, match=match):
        env.reset(options=options)
    obs2, *_ = env.step(np.zeros(2))
    assert env.observation_space.contains(obs2)


BAD_ACTIONS = [
    (np.array([np.nan, 0.0]), "finite"),
    (np.array([0.0, np.inf]), "finite"),
    (np.zeros(3), "shape"),
    ("close", "action"),
]


@pytest.mark.parametrize(
    ("action", "match"), BAD_ACTIONS, ids=["nan", "inf", "wrong-shape", "string"]
)
def test_bad_actions_are_refused_and_env_keeps_working(action, match):
    env = FrictionlessGraspEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)
    obs, *_ = env.step(np.zeros(2))
    assert env.observation_space.contains(obs)


def test_out_of_range_actions_act_like_the_bound():
    env = FrictionlessGraspEnv(palm_control=True)
    results = []
    for action in ([5.0, -7.0, 3.0, 2.0, -9.0], [1.0, -1.0, 1.0, 1.0, -1.0]):
        env.reset(seed=0)
        results.append(env.step(np.array(action)))
    assert _same(results[0], results[1])
    assert results[0][-1]["finger_angles"][0] == pytest.approx(-math.pi / 2 + 0.05)


# ---------------------------------------------------------------------- shapes
@pytest.mark.parametrize("seed", range(4))
def test_random_polygons_are_convex_ccw_stable_and_in_range(seed):
    rng = np.random.default_rng(seed)
    ranges = DEFAULT_SHAPE_RANGES
    for _ in range(25):
        v = random_convex_polygon(rng, ranges["vertices"], ranges["size"], ranges["aspect"])
        assert ranges["vertices"][0] <= len(v) <= ranges["vertices"][1]
        assert geo.is_convex_ccw(v) and geo.turns_once(v)
        diameter = np.linalg.norm(v[:, None] - v[None], axis=-1).max()
        assert ranges["size"][0] - 1e-12 <= diameter <= ranges["size"][1] + 1e-12
        # Resting on edge 0 on the support, centroid above the edge (statically stable).
        assert v[0, 1] == 0.0 and v[1, 1] == 0.0 and v[:, 1].min() >= 0.0
        c = geo.polygon_centroid(v)
        assert abs(c[0]) < 1e-12 and v[0, 0] < c[0] < v[1, 0]


def test_randomized_scenes_fit_the_hand_and_vary():
    ranges = {"vertices": (3, 6), "mass": (0.1, 0.2)}
    env = FrictionlessGraspEnv(shape_randomizer=ranges)
    masses, counts = set(), set()
    for seed in range(6):
        env.reset(seed=seed)
        scene = env.scene
        masses.add(scene.object.mass)
        counts.add(len(scene.object.vertices_B))
        assert 0.1 <= scene.object.mass <= 0.2 and 3 <= len(scene.object.vertices_B) <= 6
        assert scene.palm.pose[0] == pytest.approx(scene.object.start_pose[0])
    assert len(masses) == 6 and len(counts) > 1


# ---------------------------------------------------------------------- observations, rewards
# Square objects wedged between two fingertips are slow in the simulator (seconds per move,
# object angle growing without bound: reported with reproducers), so their rollouts start
# with the fingers hanging; the others start touching the object.
_SLOW_WEDGE = {"square", "heavy_square"}
ROLLOUT_CASES = [
    (name, {"start": "scene" if name in _SLOW_WEDGE else "preliftoff"})
    for name in grasp_env.bundled_scenes()
] + [("fig13", {"shape_randomizer": True, "palm_control": True, "start": "random"})]


@pytest.mark.parametrize(
    ("scene", "kwargs"), ROLLOUT_CASES, ids=[*grasp_env.bundled_scenes(), "randomizer"]
)
def test_observations_stay_in_space_and_rewards_add_up(scene, kwargs):
    env = FrictionlessGraspEnv(scene=scene, **kwargs)
    for obs, reward, _, _, info in _rollout(env, seed=0, steps=12):
        assert env.observation_space.contains(obs)
        assert reward == pytest.approx(sum(info[k] for k in REWARD_KEYS), abs=1e-12)
        if "sim_error" not in info:
            assert info["is_success"] == (
                info["form_closure"] and all(c["body"] != "support" for c in info["contacts"])
            )


def test_observation_layout():
    env = FrictionlessGraspEnv(scene="square")
    obs, _ = env.reset(seed=0)
    scene = env.scene
    n = 12
    assert obs[0] == pytest.approx(scene.palm.pose[0] - scene.object.start_pose[0])
    assert obs[1] == pytest.approx(scene.palm.pose[1])
    assert obs[3] == pytest.approx(-math.pi / 2) and obs[4] == pytest.approx(-math.pi / 2)
    v = obs[13 : 13 + 2 * n].reshape(n, 2)
    assert np.allclose(v[:4], scene.object.vertices_B) and np.all(v[4:] == 0)
    assert np.array_equal(obs[13 + 2 * n : 13 + 3 * n], [1] * 4 + [0] * 8)
    support_count, support_force = obs[13 + 3 * n : 15 + 3 * n]
    assert support_count == 2 and support_force == pytest.approx(1.0)
    assert obs[-3] == 0 and obs[-2] == 10 and obs[-1] == 0
    low, high = observation_bounds(n)
    assert np.array_equal(env.observation_space.low, low)
    assert np.array_equal(env.observation_space.high, high)


@pytest.mark.parametrize(
    "kwargs",
    [{}, {"palm_control": True, "shape_randomizer": True}, {"start": "preliftoff"}],
    ids=["default", "palm-randomizer", "preliftoff"],
)
def test_observation_follows_each_step_state(kwargs):
    """Every observation's hand, object and contact entries, recomputed here from the step's
    info (contacts counted and their forces summed per body), also on steps where the hand
    moves clear of the object or does not move (every fourth action is zero) and the env
    keeps the contact part it had."""
    env = FrictionlessGraspEnv(**kwargs)
    n = env.max_vertices
    rng = np.random.default_rng(5)
    obs, info = env.reset(seed=3)
    y0, kept = info["object_pose"][1], 0
    for k in range(200):
        action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        obs, _, terminated, truncated, info = env.step(action * (k % 4 != 0))
        scene = env.scene
        w, weight, x0 = scene.palm.width, scene.object_weight, scene.object.start_pose[0]
        x_p, y_p, th_p = info["palm_pose"]
        x_o, y_o, th_o = info["object_pose"]
        c, s = math.cos(th_p), math.sin(th_p)
        dx, dy = x_o - x_p, y_o - y_p
        expected = [
            (x_p - x0) / w, y_p / w, th_p, *info["finger_angles"], (x_o - x0) / w, y_o / w,
            math.sin(th_o), math.cos(th_o), (c * dx + s * dy) / w, (-s * dx + c * dy) / w,
            math.sin(th_o - th_p), math.cos(th_o - th_p),
        ]  # fmt: skip
        per_body = np.zeros(2 * len(geo.BODY_NAMES))
        for contact in info["contacts"]:
            k = 2 * geo.BODY_NAMES.index(contact["body"])
            per_body[k] += 1.0
            per_body[k + 1] += contact["force"] / weight
        grip = info["grip_force"] / weight if info["form_closure"] else 10.0
        expected += [*per_body, float(info["form_closure"]), grip, (y_o - y0) / w]
        tail = np.concatenate([obs[:13], obs[13 + 3 * n :]])
        low, high = observation_bounds(n)
        bounds = (
            np.concatenate([low[:13], low[13 + 3 * n :]]),
            np.concatenate([high[:13], high[13 + 3 * n :]]),
        )
        np.testing.assert_allclose(
            tail, np.clip(expected, *bounds).astype(np.float32), rtol=1e-6, atol=1e-6
        )
        kept += info["events"] == [] and all(c["body"] == "support" for c in info["contacts"])
        if terminated or truncated:
            obs, info = env.reset()
            y0 = info["object_pose"][1]
    assert kept > 10, kept


def test_form_closure_lift_then_drop_terminates_with_penalty():
    env = FrictionlessGraspEnv(start="preliftoff", reward_ctrl_weight=0.01)
    env.reset(seed=0)
    # Squeeze: the fig13 object tips up into the hand, off the support, in form closure.
    _, reward, terminated, _, info = _close_until(env, lambda i: i["is_success"])
    assert not terminated and info["form_closure"]
    assert info["reward_form_closure"] == 10.0
    assert 0.0 < info["reward_grip"] <= 0.1
    assert 0 < info["grip_force"] / grasp_env.load_scene("fig13").object_weight < 10
    assert info["reward_ctrl"] == pytest.approx(-0.02)
    # The bonus is paid once per episode.
    _, _, _, _, info = env.step(np.zeros(2))
    assert info["is_success"] and info["reward_form_closure"] == 0.0
    # Open the fingers: the object falls back onto the support, a drop.
    for _ in range(30):
        _, reward, terminated, truncated, info = env.step(-np.ones(2))
        if terminated:
            break
    assert terminated and not truncated and info["dropped"]
    assert any(c["body"] == "support" for c in info["contacts"])
    assert info["reward_drop"] == -10.0
    assert reward == pytest.approx(sum(info[k] for k in REWARD_KEYS))


def test_lift_shaping_is_potential_based():
    gamma = 0.9
    env = FrictionlessGraspEnv(start="preliftoff", gamma=gamma, reward_lift_weight=2.0)
    _, info = env.reset(seed=0)
    y0 = info["object_pose"][1]
    phi_prev = 0.0
    for _ in range(10):
        _, _, terminated, _, info = env.step(np.ones(2))
        phi = 0.0 if terminated else 2.0 * (info["object_pose"][1] - y0)
        assert info["reward_lift"] == pytest.approx(gamma * phi - phi_prev, abs=1e-12)
        phi_prev = phi


def test_simulation_error_terminates_with_state_unchanged():
    """A move the simulator cannot follow within its work limit ends the episode where it
    is: the same observation and pose, the lift potential undone (zero here), the reason in
    ``info["sim_error"]``. (Here the work limit is one pose solve, for a move that touches
    the object.)"""
    env = FrictionlessGraspEnv(start="preliftoff")
    obs, info = env.reset(seed=0)
    env.simulator.model = env.simulator.model._replace(max_solves=1)
    obs2, reward, terminated, truncated, info2 = env.step(np.ones(2))
    assert terminated and not truncated and "WorkLimitError" in info2["sim_error"]
    assert np.array_equal(obs, obs2) and np.array_equal(info["object_pose"], info2["object_pose"])
    assert reward == 0.0 and not info2["dropped"]


#: The analysis' reference LP failing where the compiled one could not decide a grip: the
#: compiled functions run interpreted (``NUMBA_DISABLE_JIT=1``), so that they can be patched.
ANALYSIS_ERROR = """
import numpy as np, pytest
import grasp_env
from grasp_env.envs import episode
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.kernel import analysis

env = FrictionlessGraspEnv(start="preliftoff")
obs, info = env.reset(seed=0)
y0 = info["object_pose"][1]
analysis.grip_objective = lambda *a: (analysis.GRIP_UNDECIDED, np.nan)
def fail(state):
    raise grasp_env.SolverError("grip LP: numerical trouble", status="inconsistent")
episode.reference_grip = fail
for _ in range(40):  # closing makes four contacts: form closure, then the grip LP runs
    before = env.state
    new_obs, reward, terminated, _, info = env.step(np.ones(2))
    if terminated:
        break
    obs = new_obs
assert terminated and "numerical trouble" in info["sim_error"], info
assert env.state is before and np.array_equal(new_obs, obs)
# the lift shaping's terminal step: Phi = 0 there
assert reward == info["reward_lift"] == pytest.approx(-(before.object_pose[1] - y0))
episode.reference_grip = lambda state: np.inf
env.reset(seed=0)
assert env.step(np.ones(2))[2] is False
print("ok")
"""


def test_analysis_error_terminates_with_state_unchanged():
    """A failure of the analysis' LPs ends the episode like a simulator failure; the env
    resets and goes on afterwards."""
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, "-c", ANALYSIS_ERROR], capture_output=True, text=True, timeout=600,
        env={**os.environ, "NUMBA_DISABLE_JIT": "1", "SDL_VIDEODRIVER": "dummy"},
    )  # fmt: skip
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stderr[-3000:]


def test_hold_reward_is_paid_every_step_the_grasp_holds():
    env = FrictionlessGraspEnv(start="preliftoff", reward_hold_weight=0.5)
    env.reset(seed=0)
    held = 0
    for _ in range(60):
        _, reward, terminated, _, info = env.step(np.ones(2) * (held < 3))
        assert info["reward_hold"] == (0.5 if info["is_success"] else 0.0)
        assert reward == pytest.approx(sum(info[k] for k in REWARD_KEYS))
        held += info["is_success"]
        assert not terminated
    assert held > 10


@pytest.mark.parametrize("seed", range(4))
def test_placement_start_is_the_planners_first_placement(seed):
    """``start="placement"``: the hand where the planner's pre-liftoff phase first puts it,
    in a valid state (no penetration, contacts as independent geometry finds them)."""
    from grasp_env.testing import check_state

    env = FrictionlessGraspEnv(shape_randomizer=True, palm_control=True, start="placement")
    env.reset(seed=1_000_000 + seed)
    state = env.state
    expected, _ = grasp_env.planning.first_placement(grasp_env.Simulator(env.scene))
    assert np.array_equal(state.hand, expected.hand)
    assert np.array_equal(state.object_pose, expected.object_pose)
    chk = check_state(state.scene, state.object_pose, state.hand, state.contacts, env.simulator.tol)
    assert not chk.violations, chk
    assert {"finger1", "finger2"} & {c.body for c in state.contacts}


def _contact_positions(scene, h, contacts) -> list[float]:
    """Mean position of each hand body's contacts along it, from the conventions' frames:
    palm x from its centre over the width, finger distance from its joint over its length."""
    w = scene.palm.width
    c, s = math.cos(h[2]), math.sin(h[2])
    out = []
    for k, body in enumerate(("palm", "finger1", "finger2")):
        if k == 0:
            origin, angle, length = h[:2], h[2], w
        else:
            side = -0.5 if k == 1 else 0.5
            origin = h[:2] + side * w * np.array([c, s])
            angle, length = h[2] + h[2 + k], scene.fingers[k - 1].length
        u = np.array([math.cos(angle), math.sin(angle)])
        xs = [float((ct["point"] - origin) @ u) / length for ct in contacts if ct["body"] == body]
        out.append(sum(xs) / len(xs) if xs else 0.0)
    return out


def test_hand_features_follow_each_step():
    """The ``hand_features`` block: contact positions recomputed from the step's info, and
    :func:`grasp_env.sim.proximity.hand_features` (tested against independent geometry) in
    palm widths; the rest of the observation as without it."""
    from grasp_env.sim import proximity

    env = FrictionlessGraspEnv(shape_randomizer=True, palm_control=True, start="placement",
                               hand_features=True)  # fmt: skip
    plain = FrictionlessGraspEnv(shape_randomizer=True, palm_control=True, start="placement")
    n = env.max_vertices
    assert env.observation_space.shape == (27 + 3 * n + proximity.N_FEATURES,)
    low, high = observation_bounds(n, hand_features=True)
    assert np.array_equal(env.observation_space.low, low)
    rng = np.random.default_rng(2)
    obs, info = env.reset(seed=7)
    base, _ = plain.reset(seed=7)
    touched = 0
    for _ in range(120):
        action = rng.uniform(-1, 1, 5).astype(np.float32)
        obs, _, terminated, truncated, info = env.step(action)
        base, *_ = plain.step(action)
        assert np.array_equal(obs[: len(base)], base)
        scene, h = env.scene, np.concatenate([info["palm_pose"], info["finger_angles"]])
        expected = _contact_positions(scene, h, info["contacts"])
        m = env.simulator.model
        features = proximity.hand_features(
            m.points, m.body, m.n_object, m.n_vertices, m.half, info["object_pose"], h
        )
        expected += list(features / scene.palm.width)
        np.testing.assert_allclose(
            obs[len(base) :], np.clip(expected, low[len(base) :], high[len(base) :]),
            rtol=1e-6, atol=1e-6,
        )  # fmt: skip
        touched += any(x != 0.0 for x in expected[1:3])
        if terminated or truncated:
            obs, info = env.reset()
            base, _ = plain.reset(seed=None)
            break
    assert touched > 5


def test_always_compute_grip_reports_y_star_outside_closure():
    env = FrictionlessGraspEnv(always_compute_grip=True)
    _, info = env.reset(seed=0)
    weight = grasp_env.load_scene("fig13").object_weight
    assert not info["form_closure"] and info["grip_force"] == math.inf
    assert info["grip_objective"] == pytest.approx(weight)  # resting on the support: y* = W


def test_random_shapes_use_no_vectorized_trigonometry(monkeypatch) -> None:
    """The random shapes' vertices come from the C library's cosine and sine, one angle at a
    time: numpy's array versions may be vectorized on one processor and not on another,
    which changes the last bit of a shape, and from it where a trajectory crosses a fold."""

    def vectorized(*args, **kwargs):
        raise AssertionError("numpy's array trigonometry in a random shape")

    class Numpy:  # numpy, but for its cosine and sine, as the shapes module sees it
        cos = sin = staticmethod(vectorized)

        def __getattr__(self, name):
            return getattr(np, name)

    env = FrictionlessGraspEnv(shape_randomizer={})
    monkeypatch.setattr(shapes, "np", Numpy())
    for seed in range(5):
        env.reset(seed=seed)
        random_convex_polygon(np.random.default_rng(seed), (3, 12), (0.2, 0.6), (1.0, 3.0))
