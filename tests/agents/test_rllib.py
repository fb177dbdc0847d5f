"""RLlib PPO (agents.train_rllib): the config file, the command's checks, and a tiny run on a
local Ray instance whose checkpoint is loaded again and acts. Needs ray[rllib]."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("ray")
pytest.importorskip("ray.rllib")

from agents import rllib_config as rc
from agents import rllib_training as rt
from agents import train_rllib as tr
from agents.config import load_config
from agents.rllib_policy import RLlibPolicy, load_run

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "rllib_ppo.yml"
ENTRIES = list(load_config(CONFIG))
BASE = ["--env", "FrictionlessGrasp-v0", "--num-env-runners", "1"]


@pytest.mark.parametrize("env_id", ENTRIES, ids=ENTRIES)
def test_config_entry_builds(env_id):
    entry = rc.get_entry(load_config(CONFIG), env_id)
    rc.EntryEnv(rc.env_config(entry, env_id)).close()
    config = rc.build_config(entry, env_id, 2, seed=0)
    config.validate()
    assert config.train_batch_size_per_learner == 1024
    assert config.get_rollout_fragment_length() == 512  # n_steps of configs/ppo.yml


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--num-env-runners", "1"], "--env"),
        (["--env", "FrictionlessGrasp-v0", "--num-env-runners", "-1"], "'-1'"),
        (["--env", "NoSuchEnv-v0", "--num-env-runners", "1"], "'NoSuchEnv-v0' is not in the"),
        ([*BASE, "--config", "missing.yml"], "'missing.yml'"),
        ([*BASE, "--address", "a:b"], "got 'a:b'"),
        ([*BASE, "--ship-code"], "--ship-code needs --address"),
        ([*BASE, "--address", "auto", "--num-cpus", "2"], "--num-cpus is for a local"),
        ([*BASE, "--out", "agents"], "inside the repository"),
        ([*BASE, "--iterations", "1", "--timesteps", "5"], "not allowed with"),
    ],
    ids=[
        "no-env",
        "negative-runners",
        "unknown-env",
        "missing-config",
        "bad-address",
        "ship-code-local",
        "num-cpus-cluster",
        "out-in-repo",
        "both-stops",
    ],
)
def test_command_names_the_bad_value(argv, message, capsys):
    with pytest.raises(SystemExit):
        tr.main(argv)
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"training": {"no_such_key": 1}}, "training:"),
        ({"env_runners": {"num_env_runners": 4}}, "set on the command line"),
        ({"lr": 0.1}, "unknown keys ['lr']"),
        ({"training": {"minibatch_size": 4096}}, "minibatch_size"),
        ({"env_kwargs": {"start": "sideways"}}, "cannot build its env"),
        ({"env_wrapper": "my.Wrapper"}, "my.Wrapper"),
    ],
    ids=[
        "unknown-setting",
        "runners-in-file",
        "unknown-key",
        "invalid-ppo",
        "bad-env-kwarg",
        "bad-wrapper",
    ],
)
def test_bad_entry_is_named(entry, message, tmp_path, capsys):
    config = tmp_path / "bad.yml"
    config.write_text(yaml.safe_dump({"FrictionlessGrasp-v0": entry}))
    with pytest.raises(SystemExit):
        tr.main([*BASE, "--config", str(config)])
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err


def test_iteration_without_samples_goes_on():
    """An iteration in which no env runner returned samples in time (RLlib reports no env
    step count then) counts 0 steps and says so; training goes on to its step budget."""
    from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME

    results = [{}, *({ENV_RUNNER_RESULTS: {NUM_ENV_STEPS_SAMPLED_LIFETIME: n}} for n in (64, 128))]
    algo = SimpleNamespace(train=iter(results).__next__)
    lines = []
    stats = rt.train(algo, timesteps=100, log=lines.append)
    assert stats["iterations"] == 3 and stats["timesteps"] == 128
    assert "env steps        0" in lines[0] and "no env runner returned samples" in lines[0]
    assert "no env runner" not in lines[1] + lines[2]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Path, str]:
    """A run of the command: two iterations with 2 env runners on a local Ray instance
    (tiny batches, 20-step episodes); returns its directory and what it printed."""
    tmp = tmp_path_factory.mktemp("rllib")
    entry = yaml.safe_load(CONFIG.read_text())["FrictionlessGrasp-v0"]
    entry["env_kwargs"]["max_episode_steps"] = 20
    entry["training"].update(train_batch_size_per_learner=64, minibatch_size=32, num_epochs=1)
    config = tmp / "tiny.yml"
    config.write_text(yaml.safe_dump({"FrictionlessGrasp-v0": entry}))
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        tr.main(
            [
                *("--env", "FrictionlessGrasp-v0", "--num-env-runners", "2", "--num-cpus", "2"),
                *("--config", str(config), "--iterations", "2"),
                *("--out", str(tmp / "run")),
            ]
        )
    return tmp / "run", out.getvalue()


@pytest.mark.slow
def test_run_reports_and_saves(run):
    path, printed = run
    assert printed.count("iter ") == 2 and "success" in printed
    assert "env runners on: 127.0.0.1 x2" in printed  # loopback only
    stats = json.loads((path / "train_stats.json").read_text())
    assert stats["iterations"] == 2 and stats["timesteps"] >= 128
    assert stats["num_env_runners"] == 2
    checkpoint, env_id, saved = load_run(path)
    assert checkpoint == path / "checkpoint"
    assert env_id == "FrictionlessGrasp-v0" and saved["env_kwargs"]["max_episode_steps"] == 20


@pytest.mark.slow
def test_checkpoint_acts(run):
    policy = RLlibPolicy(load_run(run[0])[0])
    env = gym.make("FrictionlessGrasp-v0")
    obs, _ = env.reset(seed=0)
    action = policy.act(obs)
    assert env.action_space.contains(action)
    np.testing.assert_array_equal(policy.act(obs), action)  # deterministic, filter frozen
    env.step(action)
    env.close()


@pytest.mark.slow
def test_algorithm_restores(run):
    """``Algorithm.from_checkpoint`` in a new Ray session: same iteration, same weights."""
    import ray
    from ray.rllib.algorithms.algorithm import Algorithm

    checkpoint = load_run(run[0])[0]
    trained = RLlibPolicy(checkpoint).module.state_dict()
    rt.start_ray(None, 2, ship_code=False)
    try:
        algo = Algorithm.from_checkpoint(checkpoint)
        assert algo.iteration == 2
        restored = algo.get_module().state_dict()  # the env runners' inference-only module
        assert restored
        for key, value in restored.items():
            np.testing.assert_array_equal(value.numpy(), trained[key].numpy())
        algo.stop()
    finally:
        ray.shutdown()


@pytest.mark.slow
def test_evaluation_table_has_the_checkpoint(run, tmp_path):
    pytest.importorskip("matplotlib")
    pytest.importorskip("imageio")
    from agents import episodes as ep
    from agents import evaluate as ev

    spec = ep.rllib_spec(run[0])
    assert spec.name == "rllib_FrictionlessGrasp-v0"
    assert spec.env_kwargs == {"max_episode_steps": 20}  # no reward weights
    random = ep.PolicySpec("random", "random", ep.RANDOM_KWARGS)
    rows, _ = ev.evaluate([spec, random], tmp_path, episodes=1, scenes=["fig13"], max_steps=10)
    assert {r["policy"] for r in rows} == {spec.name, "random"}
    assert all(r["errors"] == 0 for r in rows)
    assert spec.name in (tmp_path / "summary.md").read_text()


def test_evaluate_refuses_a_path_that_is_no_checkpoint(tmp_path, capsys):
    from agents import evaluate as ev

    with pytest.raises(SystemExit):
        ev.main(["--models", "--rllib-checkpoint", str(tmp_path), "--out", str(tmp_path)])
    assert "is not an RLlib checkpoint" in capsys.readouterr().err


def test_evaluation_set_up_follows_the_env_id(tmp_path):
    """A run on the random-shapes id is evaluated with palm control, the suite choosing the
    scene or shapes and the start; reward weights stay the env's."""
    from agents import episodes as ep

    (tmp_path / "checkpoint").mkdir()
    (tmp_path / "checkpoint" / "rllib_checkpoint.json").write_text("{}")
    entry = rc.get_entry(load_config(CONFIG), "FrictionlessGraspRandomShapes-v0")
    (tmp_path / "config.yml").write_text(
        yaml.safe_dump({"FrictionlessGraspRandomShapes-v0": entry})
    )
    spec = ep.rllib_spec(tmp_path)
    assert spec.name == "rllib_FrictionlessGraspRandomShapes-v0"
    assert spec.env_kwargs == {"palm_control": True}  # the suites set the start
    assert spec.model_dir == str(tmp_path / "checkpoint")
