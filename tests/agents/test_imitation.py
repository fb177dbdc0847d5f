"""agents.imitation, agents.expert, agents.cloning: expert data from the scripted planner,
behaviour cloning, the saved network-only model, the command's argument checks."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from agents import cloning, imitation
from agents import expert as ex
from agents.episodes import ppo_spec
from agents.models import load_agent, network_action
from agents.scripted import ScriptedPolicy

#: A training seed whose shape the planner lifts from its placement.
SEED = 600


@pytest.fixture(scope="module")
def expert():
    return ex.expert_episode(("placement", SEED, 2))


def test_expert_actions_are_in_the_action_space(expert):
    space = ex.make_env("placement").action_space
    assert expert["success"] and expert["steps"] == len(expert["act"]) > 0
    assert expert["act"].dtype == np.float32 and expert["act"].shape[1] == 5
    assert np.all(expert["act"] >= space.low) and np.all(expert["act"] <= space.high)
    assert expert["obs"].shape == (len(expert["act"]), 72)
    ex.check_actions(expert["act"], space)
    with pytest.raises(ValueError, match="outside"):
        ex.check_actions(expert["act"] * 1.5 + 0.5, space)


def test_expert_action_is_the_planners_and_leaves_the_env_alone():
    env = ex.make_env("placement")
    obs, info = env.reset(seed=SEED)
    state = env.unwrapped.state
    label = ex.expert_action(env)
    assert env.unwrapped.state is state
    policy = ScriptedPolicy(env)
    policy.reset(obs, info)
    np.testing.assert_array_equal(label, policy.act(obs))


def test_behaviour_cloning_reduces_the_loss(expert):
    model, norm = cloning.new_model([32], seed=0)
    cloning.set_normalization(norm, expert["obs"])
    before = cloning.mse(model, norm, expert["obs"], expert["act"])
    history = cloning.behaviour_clone(
        model, norm, expert["obs"], expert["act"], epochs=30, batch_size=16, lr=3e-3
    )
    after = cloning.mse(model, norm, expert["obs"], expert["act"])
    assert after < 0.5 * before
    assert history[-1]["train_loss"] < history[0]["train_loss"]


def test_saved_model_acts_from_the_observation_alone(expert, tmp_path):
    model, norm = cloning.new_model([32], seed=0)
    cloning.set_normalization(norm, expert["obs"])
    cloning.save_model(model, norm, tmp_path, {"test": True}, [32])
    loaded, loaded_norm, _, entry = load_agent(tmp_path)
    assert entry["env_id"] == ex.ENV_ID and entry["env_kwargs"]["hand_features"]
    spec = ppo_spec(tmp_path)
    assert spec.test_time == "network" and spec.wrapper is None
    # nothing reachable from the policy is the planner, the simulator or an env
    blob = pickle.dumps(loaded.policy)
    for name in (b"agents.scripted", b"grasp_env.simulator", b"grasp_env.planning"):
        assert name not in blob
    assert loaded.get_env() is None and getattr(loaded_norm, "venv", None) is None
    for value in vars(loaded_norm).values():  # statistics and settings only
        assert not type(value).__module__.startswith(("agents", "grasp_env"))
    env = ex.make_env("scene")
    obs, _ = env.reset(seed=3)
    action = network_action(loaded, loaded_norm, obs)
    assert env.action_space.contains(action.astype(np.float32))
    np.testing.assert_array_equal(action, network_action(loaded, loaded_norm, obs))


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--seed", "999999"], ["--seed 999999", "1000000"]),
        (["--net-arch", "0"], ["--net-arch", "'0'"]),
        (["--query-every", "0"], ["--query-every", "'0'"]),
        (["--lr", "nan"], ["--lr", "'nan'"]),
        (["--data", "no/such.npz"], ["--data", "no/such.npz"]),
        (["--report", "no/such"], ["--report", "no/such"]),
    ],
)
def test_argument_errors_name_the_flag_and_value(argv, words, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        imitation.main([*argv, "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    for word in words:
        assert word in err
    assert not (tmp_path / "out" / "model.zip").exists()


def test_interleave_spreads_both_starts():
    merged = ex.interleave(list(range(6)), ["a", "b"])
    assert sorted(map(str, merged)) == sorted(map(str, [*range(6), "a", "b"]))
    assert merged[:4].count("a") == 1


def test_dagger_labels_weigh_dagger_weight():
    data = {"round": np.array([0, 0, 1, 2], np.int16)}
    np.testing.assert_array_equal(cloning.sample_weights(data, 5.0), [1, 1, 5, 5])
