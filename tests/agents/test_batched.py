"""The batched env as an SB3 ``VecEnv`` (``agents.batched.make_vec_env``): SB3's conventions
(``dones``, ``terminal_observation``, ``TimeLimit.truncated``, ``is_success``), checked
against single envs stepped with the same actions, and SB3's wrappers on top."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from agents.batched import make_vec_env
from grasp_env.envs.vector import INFO_FLAGS, INFO_VALUES

ENV_ID, N, STEPS, SEED = "FrictionlessGraspLift-v0", 3, 80, 4
#: A short time limit so that episodes end by truncation; the fingers opening every fourth
#: step drop lifted objects (a termination).
KWARGS = {"time_limit": 40, "shape_pool": 8}


def _actions(steps: int, n: int, size: int) -> np.ndarray:
    """Random actions, the fingers closing in three steps of four."""
    rng = np.random.default_rng(2)
    out = rng.uniform(-1, 1, (steps, n, size)).astype(np.float32)
    closing = (np.arange(steps) % 4 != 3)[:, None, None]
    out[:, :, :2] = np.where(closing, np.abs(out[:, :, :2]), -np.abs(out[:, :, :2]))
    return out


def test_steps_follow_single_envs_with_sb3s_conventions():
    vec = make_vec_env(ENV_ID, N, seed=SEED, **KWARGS)
    singles = [gym.make(ENV_ID, **KWARGS) for _ in range(N)]
    obs = vec.reset()
    for i, env in enumerate(singles):
        np.testing.assert_array_equal(obs[i], env.reset(seed=SEED + i)[0])
    ends = {"terminated": 0, "truncated": 0}
    for actions in _actions(STEPS, N, vec.action_space.shape[0]):
        obs, rewards, dones, infos = vec.step(actions)
        assert rewards.dtype == np.float32 and len(infos) == N
        for i, env in enumerate(singles):
            o, r, term, trunc, info = env.step(actions[i])
            assert rewards[i] == np.float32(r) and dones[i] == (term or trunc)
            for key in (*INFO_FLAGS, *INFO_VALUES):
                assert infos[i][key] == info[key] or np.isnan(info[key]), key
            if term or trunc:
                ends["terminated" if term else "truncated"] += 1
                np.testing.assert_array_equal(infos[i]["terminal_observation"], o)
                assert infos[i]["TimeLimit.truncated"] == (trunc and not term)
                o, _ = env.reset()
            else:
                assert "terminal_observation" not in infos[i]
            np.testing.assert_array_equal(obs[i], o)
    assert ends["terminated"] > 0 and ends["truncated"] > 0  # both kinds of end compared


def test_vec_monitor_and_vec_normalize_on_top():
    vec = make_vec_env(ENV_ID, N, seed=SEED, **KWARGS)
    twin = make_vec_env(ENV_ID, N, seed=SEED, **KWARGS)
    wrapped = VecNormalize(VecMonitor(vec), norm_obs=True, norm_reward=True)
    wrapped.reset()
    twin.reset()
    returns, lengths, episodes = np.zeros(N), np.zeros(N, dtype=int), []
    for actions in _actions(STEPS, N, vec.action_space.shape[0]):
        obs, _, dones, infos = wrapped.step(actions)
        raw_obs, raw_rewards, raw_dones, _ = twin.step(actions)
        np.testing.assert_array_equal(dones, raw_dones)
        np.testing.assert_array_equal(wrapped.get_original_obs(), raw_obs)
        np.testing.assert_array_equal(wrapped.get_original_reward(), raw_rewards)
        assert np.all(np.isfinite(obs))
        returns += raw_rewards
        lengths += 1
        for i in np.flatnonzero(dones):
            episode = infos[i]["episode"]  # VecMonitor's summary of the episode
            assert episode["l"] == lengths[i]
            assert episode["r"] == pytest.approx(returns[i], abs=1e-5)
            episodes.append(episode)
            returns[i], lengths[i] = 0.0, 0
    assert episodes


def test_null_env_follows_sb3s_conventions():
    """The PPO benchmark's null env: SB3's episode ends, with the given spaces."""
    from benchmarks.ppo_throughput import null_vec_env

    single = gym.make(ENV_ID, shape_pool=2)
    venv = VecMonitor(null_vec_env(3, single.observation_space, single.action_space, length=4))
    obs = venv.reset()
    assert obs.shape == (3, *single.observation_space.shape)
    ends, lengths = [], [[], [], []]
    for _ in range(8):
        obs, rewards, dones, infos = venv.step(np.zeros((3, *single.action_space.shape)))
        assert not rewards.any() and obs.dtype == single.observation_space.dtype
        ends.append(dones.copy())
        for i in np.flatnonzero(dones):
            assert infos[i]["TimeLimit.truncated"]
            assert infos[i]["terminal_observation"].shape == single.observation_space.shape
            lengths[i].append(infos[i]["episode"]["l"])
    assert lengths == [[4, 4], [3, 4], [2, 4]]
    # the envs' episodes are staggered: env i ends first after 4 - i steps
    assert [int(np.flatnonzero(np.array(ends)[:, i])[0]) + 1 for i in range(3)] == [4, 3, 2]
    assert np.array(ends).sum(axis=0).tolist() == [2, 2, 2]


@pytest.mark.parametrize("n_envs", [0, -1, 2.5, True, 10**30])
def test_bad_n_envs_is_named_as_the_caller_named_it(n_envs):
    with pytest.raises(ValueError, match=rf"n_envs must be an integer .*, got {n_envs!r}"):
        make_vec_env("FrictionlessGrasp-v0", n_envs)


@pytest.mark.parametrize("seed", [-1, 1.5, "a", True, math.nan])
def test_bad_seed_is_named(seed):
    with pytest.raises(ValueError, match=r"seed must be an integer >= 0"):
        make_vec_env("FrictionlessGrasp-v0", 2, seed=seed)


@pytest.mark.parametrize("env_id", ["CartPole-v1", "Nope-v0", "FrictionlessGrasp", None, 5])
def test_an_id_without_a_batched_env_is_named(env_id):
    with pytest.raises(ValueError, match=rf"env_id {env_id!r} has no batched env"):
        make_vec_env(env_id, 2)


def test_n_envs_is_not_given_as_num_envs():
    with pytest.raises(TypeError, match="as n_envs, not num_envs"):
        make_vec_env("FrictionlessGrasp-v0", 2, num_envs=3)


def test_a_refused_seed_or_reset_leaves_the_env_usable():
    """A bad seed is refused when it is given; bad options, known only at the reset, are
    dropped with the reset that refuses them, so the next reset goes on."""
    vec, twin = (make_vec_env("FrictionlessGrasp-v0", 2, seed=0) for _ in range(2))
    vec.reset()
    twin.reset()
    for seed in (-1, 1.5, "x"):
        with pytest.raises(ValueError, match="seed must be an integer >= 0"):
            vec.seed(seed)
    vec.set_options({"palm": [0.0, 9.0, 0.0]})
    with pytest.raises(ValueError, match="palm"):
        vec.reset()
    vec.seed(5)
    twin.seed(5)
    np.testing.assert_array_equal(vec.reset(), twin.reset())


@pytest.mark.parametrize("indices", [5, -1, [0, 2], 1.0])
def test_bad_indices_are_named(indices):
    vec = make_vec_env("FrictionlessGrasp-v0", 2)
    with pytest.raises(ValueError, match=r"indices must be an integer (in \[0, 1\]|>= 0)"):
        vec.get_attr("time_limit", indices=indices)
    assert vec.get_attr("time_limit", indices=np.int64(1)) == [200]
    assert make_vec_env("FrictionlessGrasp-v0", 2, seed=np.int64(3)).num_envs == 2
