"""The batched env (``gymnasium.make_vec``): every sub-env follows a single env made with the
same arguments, reset with the seed the batch documents and stepped with the same actions,
bit for bit, through resets, failures and any number of threads."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

from grasp_env.envs import ENV_KWARGS
from grasp_env.envs.vector import INFO_FLAGS, INFO_VALUES, FrictionlessGraspVectorEnv

#: Set-ups: every id, palm control from perturbed starts, hand features from the pre-liftoff
#: placement, random shapes from a pool. Short time limits, so that episodes end by
#: truncation as well as by drops.
CASES = [
    ("FrictionlessGrasp-v0", {"time_limit": 30}),
    ("FrictionlessGraspRandomShapes-v0", {"time_limit": 40}),
    ("FrictionlessGraspLift-v0", {"time_limit": 40, "shape_pool": 8}),
    ("FrictionlessGrasp-v0", {"start": "random", "palm_control": True, "time_limit": 25}),
    ("FrictionlessGrasp-v0", {"start": "preliftoff", "hand_features": True,
                              "always_compute_grip": True, "reward_ctrl_weight": 0.1}),
]  # fmt: skip
IDS = [f"{env_id}-{'-'.join(kw)}" for env_id, kw in CASES]


def actions(space: gym.Space, n: int, steps: int, seed: int) -> np.ndarray:
    """Random actions, the fingers closing in three steps of four (so the hand grasps)."""
    rng = np.random.default_rng(seed)
    out = rng.uniform(-1.0, 1.0, (steps, n, space.shape[0])).astype(np.float32)
    closing = (np.arange(steps) % 4 != 3)[:, None]
    out[:, :, :2] = np.where(closing[..., None], np.abs(out[:, :, :2]), -np.abs(out[:, :, :2]))
    return out


def single_episodes(env_id: str, kwargs: dict, seed: int, acts: np.ndarray) -> list:
    """What a single env does with ``acts``: reset with ``seed``, a reset without one after
    every end."""
    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    out = [("reset", obs, info)]
    for a in acts:
        obs, reward, terminated, truncated, info = env.step(a)
        out.append(("step", obs, reward, terminated, truncated, info))
        if terminated or truncated:
            obs, info = env.reset()
            out.append(("reset", obs, info))
    return out


def assert_info_equal(batch: dict, i: int, info: dict, where: str) -> None:
    for key in (*INFO_FLAGS, *INFO_VALUES):
        got, want = batch[key][i], info[key]
        assert got == want or (np.isnan(got) and np.isnan(want)), f"{where}: {key}"
    assert (batch.get("sim_error", [None] * (i + 1))[i] or None) == info.get("sim_error")


@pytest.mark.parametrize(("env_id", "kwargs"), CASES, ids=IDS)
def test_sub_envs_follow_single_envs_bit_for_bit(env_id: str, kwargs: dict) -> None:
    n, steps, seed = 3, 70, 11
    venv = gym.make_vec(env_id, num_envs=n, **kwargs)
    assert isinstance(venv, FrictionlessGraspVectorEnv)
    acts = actions(venv.single_action_space, n, steps, seed=5)
    obs, infos = venv.reset(seed=seed)
    batch = [(obs, infos)]
    for a in acts:
        batch.append(venv.step(a))
    ends = 0
    for i in range(n):
        single = single_episodes(env_id, kwargs, seed + i, acts[:, i])
        _, obs, info = single[0]
        np.testing.assert_array_equal(batch[0][0][i], obs)
        assert_info_equal(batch[0][1], i, info, f"env {i} reset")
        k = 1
        for t in range(steps):
            obs_b, reward_b, term_b, trunc_b, infos_b = batch[t + 1]
            _, obs, reward, terminated, truncated, info = single[k]
            where = f"env {i} step {t}"
            assert (reward_b[i], term_b[i], trunc_b[i]) == (reward, terminated, truncated), where
            k += 1
            if terminated or truncated:
                ends += 1
                np.testing.assert_array_equal(infos_b["final_obs"][i], obs, err_msg=where)
                assert_info_equal(infos_b["final_info"], i, info, where)
                _, obs, info = single[k]  # the next episode's first observation and info
                k += 1
            np.testing.assert_array_equal(obs_b[i], obs, err_msg=where)
            assert_info_equal(infos_b, i, info, where)
    assert ends > 0  # episodes ended, and the autoreset was compared too


def test_make_vec_declares_its_autoreset_and_spaces() -> None:
    for env_id, registered in ENV_KWARGS.items():
        venv = gym.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point")
        assert isinstance(venv, FrictionlessGraspVectorEnv)
        assert venv.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
        single = gym.make(env_id)
        assert venv.single_observation_space == single.observation_space
        assert venv.single_action_space == single.action_space
        assert venv.observation_space.shape == (4, *single.observation_space.shape)
        assert venv.envs[0].time_limit == registered["time_limit"]
        venv.close()
    # gymnasium's own vector envs of single envs stay available
    sync = gym.make_vec("FrictionlessGrasp-v0", num_envs=2, vectorization_mode="sync")
    assert type(sync).__name__ == "SyncVectorEnv"


def test_results_do_not_depend_on_the_threads_nor_the_schedule() -> None:
    """One thread, two, and two taking the episodes in an order drawn at random each step
    (the batch orders them by their last step's cost, which varies from run to run)."""
    kwargs = {"time_limit": 30, "shape_pool": 6}
    runs = []
    order = np.random.default_rng(4)
    for threads, scrambled in ((1, False), (2, False), (2, True)):
        venv = gym.make_vec(
            "FrictionlessGraspRandomShapes-v0", num_envs=5, threads=threads, **kwargs
        )
        acts = actions(venv.single_action_space, 5, 60, seed=2)
        obs, _ = venv.reset(seed=3)
        out = [obs]
        for a in acts:
            if scrambled:
                venv.unwrapped._cost[:] = order.permutation(5)
            obs, reward, terminated, truncated, _ = venv.step(a)
            out += [obs, reward, terminated, truncated]
        runs.append(out)
    for run in runs[1:]:
        for a, b in zip(runs[0], run, strict=True):
            np.testing.assert_array_equal(a, b)


def test_the_schedule_reads_no_counter_where_the_processor_has_none(monkeypatch) -> None:
    """Without a cycle counter user code may read, every cost is 0 (the index order)."""
    from numba import njit

    from grasp_env.kernel import batch

    monkeypatch.setattr(batch, "HAS_CYCLE_COUNTER", False)

    @njit(cache=False)
    def read():
        return batch.cycles()

    assert read() == 0


def test_a_step_python_takes_over_matches_the_single_env() -> None:
    """Where the compiled move gives up (here a work limit of one pose solve in sub-env 1),
    Python takes the step over as the single env does: the same ``sim_error`` end, and the
    other sub-envs go on as before."""
    kwargs = {"start": "preliftoff", "time_limit": 20}
    venv = gym.make_vec("FrictionlessGrasp-v0", num_envs=2, **kwargs)
    venv.reset(seed=0)
    sim = venv.envs[1]._episode.sim
    model = sim.model._replace(max_solves=1)
    sim.model = model
    venv._models[1] = sim.compiled_model
    single = gym.make("FrictionlessGrasp-v0", **kwargs)
    single.reset(seed=1)
    single.unwrapped.simulator.model = model
    a = np.ones((2, 2), dtype=np.float32)
    obs, reward, terminated, _, infos = venv.step(a)
    obs1, reward1, terminated1, _, info1 = single.step(a[1])
    assert terminated[1] and terminated1 and "WorkLimitError" in info1["sim_error"]
    assert infos["final_info"]["sim_error"][1] == info1["sim_error"]
    np.testing.assert_array_equal(infos["final_obs"][1], obs1)
    assert reward[1] == reward1 and not terminated[0]
    other = gym.make("FrictionlessGrasp-v0", **kwargs)
    other.reset(seed=0)
    np.testing.assert_array_equal(obs[0], other.step(a[0])[0])


def test_bad_actions_are_refused_and_change_nothing() -> None:
    venv, twin = (gym.make_vec("FrictionlessGrasp-v0", num_envs=2) for _ in range(2))
    for v in (venv, twin):
        v.reset(seed=4)
    bad = [
        np.full((2, 2), np.nan),
        np.zeros((3, 2)),
        np.zeros(2),
        np.array([["a", "b"], ["c", "d"]]),
        [[1.0, np.inf], [0.0, 0.0]],
        np.ma.array(np.zeros((2, 2)), mask=[[1, 0], [0, 0]]),
        [[0.0, 0.0], [0.0]],  # ragged
        [[True, False], [0.1, 0.2]],  # a bool among numbers, as the single env refuses it
        np.zeros((2, 2), dtype=bool),
        [[1.0, 2**2000], [0.0, 0.0]],  # beyond the float range
    ]
    for actions_ in bad:
        with pytest.raises(ValueError, match="actions"):
            venv.step(actions_)
    a = np.ones((2, 2), dtype=np.float32)
    got, want = venv.step(a), twin.step(a)
    for x, y in zip(got[:4], want[:4], strict=True):
        np.testing.assert_array_equal(x, y)
    assert got[4].keys() == want[4].keys()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"max_episode_steps": 10, "time_limit": math.nan}, "time_limit"),
        ({"max_episode_steps": 10, "time_limit": "x"}, "time_limit"),
        ({"max_episode_steps": 10, "time_limit": 0}, "time_limit"),
        ({"num_envs": 10**30}, "num_envs"),
        ({"num_envs": 0}, "num_envs"),
    ],
)
def test_bad_arguments_are_named(kwargs, name) -> None:
    """Each argument is checked before it is used: a time limit before the sooner of it and
    ``max_episode_steps`` is taken, a count of sub-envs before any is made."""
    kwargs = {"num_envs": 2} | kwargs
    with pytest.raises(ValueError, match=rf"^{name} must be an integer"):
        gym.make_vec("FrictionlessGrasp-v0", **kwargs)


def test_render_gives_a_frame_per_sub_env() -> None:
    venv = gym.make_vec("FrictionlessGrasp-v0", num_envs=2, render_mode="rgb_array")
    venv.reset(seed=0)
    venv.step(np.ones((2, 2), dtype=np.float32))
    frames = venv.render()
    assert len(frames) == 2 and all(f.shape == (480, 640, 3) for f in frames)
    # the sub-env a frame shows is the batch's, not the state it last stepped itself
    assert venv.sub_env(0).state.hand[3] > venv.envs[0].scene.initial_hand[3]
    venv.close()


def test_a_refused_reset_changes_no_sub_env() -> None:
    """A reset refused by one sub-env (here the third's seed) leaves every sub-env as it was:
    the next steps and the next unseeded reset are a twin's that never saw it."""
    venv, twin = (gym.make_vec("FrictionlessGraspRandomShapes-v0", num_envs=3) for _ in range(2))
    for v in (venv, twin):
        v.reset(seed=7)
    a = np.ones((3, 5), dtype=np.float32)
    with pytest.raises(ValueError, match="seed"):
        venv.reset(seed=[1, 2, -3])
    with pytest.raises(ValueError, match="seed"):
        venv.reset(seed=[1, 2])
    for seed in (1.5, True, np.bool_(False), "7", np.zeros((3, 1), dtype=int), {1, 2, 3}):
        with pytest.raises(ValueError, match=r"^seed must be None, an int or a list of 3"):
            venv.reset(seed=seed)
    for x, y in zip(venv.step(a)[:4], twin.step(a)[:4], strict=True):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(venv.reset()[0], twin.reset()[0])
    assert venv.call("scene")[2].name == twin.get_attr("scene")[2].name


def test_a_steps_infos_are_its_own() -> None:
    """Each step's info arrays are new: changing them changes no later step's, nor the final
    infos of an episode's end; the masks, shared by every step, are read-only."""
    venv = gym.make_vec("FrictionlessGrasp-v0", num_envs=2, time_limit=3)
    venv.reset(seed=0)
    a = np.ones((2, 2), dtype=np.float32)
    _, _, _, _, first = venv.step(a)
    first["grip_force"][:] = -1.0
    first["jammed"][:] = True
    venv.step(a)
    _, _, _, truncated, ended = venv.step(a)  # the third step: the time limit
    assert truncated.all() and "final_info" in ended
    assert not (ended["grip_force"] == -1.0).any() and not ended["jammed"].all()
    before = ended["final_info"]["form_closure"].copy()
    ended["form_closure"][:] = ~ended["form_closure"]
    np.testing.assert_array_equal(ended["final_info"]["form_closure"], before)
    with pytest.raises(ValueError, match="read-only"):
        ended["_is_success"][0] = False
