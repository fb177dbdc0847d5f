"""PPO agents: the config file, a tiny training run, and the evaluation command's outputs."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

from agents import evaluate as ev
from agents import train_ppo as tp

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "ppo.yml"
ENTRIES = list(tp.load_config(CONFIG))


@pytest.mark.parametrize("name", ENTRIES, ids=ENTRIES)
def test_config_entry_builds_its_env(name):
    entry = tp.get_entry(tp.load_config(CONFIG), name)
    tp.check_entry(name, entry)
    kwargs = tp.ppo_kwargs(entry)
    assert set(kwargs).isdisjoint(tp.ENTRY_KEYS)
    assert isinstance(kwargs["policy_kwargs"], dict)
    assert entry["n_envs"] >= 1 and entry["n_timesteps"] > 0


def test_config_has_the_two_set_ups():
    config = tp.load_config(CONFIG)
    assert config["fig13_fingers"]["env_kwargs"]["scene"] == "fig13"
    assert not config["fig13_fingers"]["env_kwargs"]["palm_control"]
    assert config["random_shapes_palm"]["env_kwargs"]["shape_randomizer"]
    assert config["random_shapes_palm"]["env_kwargs"]["palm_control"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--env-id", "no_such_entry"], "'no_such_entry' is not in the config"),
        (["--env-id", "fig13_fingers", "--config", "missing.yml"], "'missing.yml'"),
        (["--env-id", "fig13_fingers", "--n-timesteps", "-5"], "'-5'"),
        (["--env-id", "fig13_fingers", "--max-minutes", "nan"], "'nan'"),
    ],
    ids=["unknown-entry", "missing-file", "negative-steps", "nan-minutes"],
)
def test_train_command_names_the_bad_value(argv, message, capsys):
    with pytest.raises(SystemExit):
        tp.main(argv)
    assert message in capsys.readouterr().err


def test_bad_env_kwarg_is_named(tmp_path):
    config = tmp_path / "bad.yml"
    entry = {"env_id": "FrictionlessGrasp-v0", "env_kwargs": {"start": "sideways"}}
    config.write_text(yaml.safe_dump({"bad": entry}))
    with pytest.raises(ValueError, match=r"entry 'bad'.*sideways"):
        tp.check_entry("bad", tp.get_entry(tp.load_config(config), "bad"))


def test_unknown_wrapper_is_named():
    with pytest.raises(ValueError, match=r"'my\.Wrapper'"):
        tp.wrapper_specs({"env_wrapper": "my.Wrapper"})


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A PPO model trained for 256 steps on short fig13 episodes (the shipped entry's
    settings with tiny rollouts)."""
    tmp = tmp_path_factory.mktemp("ppo")
    entry = dict(tp.load_config(CONFIG)["fig13_fingers"])
    entry["env_kwargs"] = {**entry["env_kwargs"], "max_episode_steps": 16}
    entry.update(n_steps=64, batch_size=32, n_epochs=2)
    entry["policy_kwargs"] = "dict(net_arch=[16])"
    config = tmp / "tiny.yml"
    config.write_text(yaml.safe_dump({"tiny": entry}))
    return tp.train(
        config,
        "tiny",
        n_timesteps=256,
        out=tmp / "model",
        log_dir=tmp / "logs",
        vec_env="dummy",
        eval_freq=128,
        n_eval_episodes=1,
        save_freq=128,
        progress_bar=False,
    )


def test_tiny_training_saves_and_reloads(trained):
    for name in ("model.zip", "vecnormalize.pkl", "config.yml", "train_stats.json"):
        assert (trained / name).is_file(), name
    stats = json.loads((trained / "train_stats.json").read_text())
    assert stats["timesteps"] == 256 and stats["env_steps_per_s"] > 0
    logs = trained.parent / "logs"
    assert list((logs / "checkpoints").glob("*.zip"))
    assert (logs / "eval" / "evaluations.npz").is_file()
    assert list((logs / "tb").iterdir())
    header = (logs / "monitor" / "0.monitor.csv").read_text().splitlines()[1].split(",")
    assert {"is_success", "ep_reward_lift", "ep_reward_grip"} <= set(header)

    model, norm, name, entry = tp.load_agent(trained)
    assert name == "tiny" and norm is not None and not norm.training
    env = tp.make_env(entry["env_id"], entry["env_kwargs"])
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(norm.normalize_obs(obs), deterministic=True)
    assert env.action_space.contains(action.astype(np.float32))
    env.close()


def test_evaluation_writes_all_outputs(trained, tmp_path, capsys):
    pytest.importorskip("matplotlib", reason="the viz extra draws the chart")
    pytest.importorskip("imageio", reason="the viz extra writes the GIFs")
    out = tmp_path / "eval"
    ev.main(
        [
            "--models",
            str(trained),
            "--episodes",
            "2",
            "--scenes",
            "fig13",
            "--max-steps",
            "4",
            "--no-scripted",
            "--out",
            str(out),
        ]
    )
    printed = capsys.readouterr().out
    assert "| heldout | random | 2 |" in printed and "ppo_tiny" in printed
    for name in ("episodes.csv", "summary.csv", "summary.md", "summary.png"):
        assert (out / name).stat().st_size > 0, name
    for policy in ("ppo_tiny", "random"):
        assert (out / f"{policy}.gif").stat().st_size > 0, policy
    rows = (out / "episodes.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * (1 + 2)  # header + 2 policies x (1 scene + 2 shapes)


def test_policies_meet_the_same_heldout_shapes():
    vertices = slice(13, 13 + 2 * 12)  # object vertices in the observation
    obs = [
        ev.make_env(ev.PolicySpec(kind, kind, kwargs), ev.HELDOUT_KWARGS, 4).reset(
            seed=ev.HELDOUT_SEED
        )[0][vertices]
        for kind, kwargs in (("scripted", ev.SCRIPTED_KWARGS), ("random", ev.RANDOM_KWARGS))
    ]
    assert np.array_equal(obs[0], obs[1]) and np.any(obs[0] != 0)


@pytest.mark.parametrize(
    ("k", "n", "low", "high"),
    [(0, 10, 0.0, 0.2775), (10, 10, 0.7225, 1.0), (5, 10, 0.2366, 0.7634)],
    ids=["none", "all", "half"],
)
def test_wilson_interval_matches_published_values(k, n, low, high):
    lo, hi = ev.wilson(k, n)
    assert lo == pytest.approx(low, abs=1e-4) and hi == pytest.approx(high, abs=1e-4)


def test_bootstrap_interval_brackets_the_mean():
    lo, hi = ev.bootstrap_mean([1.0, 2.0, 3.0, 4.0])
    assert lo < 2.5 < hi
    assert ev.bootstrap_mean([2.0, 2.0]) == (2.0, 2.0)
    assert all(math.isnan(x) for x in ev.bootstrap_mean([]))


def test_approach_shaping_is_potential_based():
    entry = tp.get_entry(tp.load_config(CONFIG), "random_shapes_palm")
    ((cls, kwargs),) = tp.wrapper_specs(entry)
    env = cls(gym.make(entry["env_id"], **entry["env_kwargs"]), **kwargs)

    def potential(obs, info):  # independent of the wrapper's: palm-frame distance, contacts
        touching = {c["body"] for c in info["contacts"] if c["body"] != "support"}
        return -kwargs["approach"] * math.dist(obs[9:11], (0, 0)) + kwargs["touch"] * len(touching)

    obs, info = env.reset(seed=3)
    for _ in range(3):
        new, reward, terminated, _, new_info = env.step(np.array([1, 1, 0, -1, 0], np.float32))
        assert not terminated  # Phi is 0 at a terminal state
        expected = kwargs["gamma"] * potential(new, new_info) - potential(obs, info)
        assert new_info["reward_approach"] == pytest.approx(expected, abs=1e-9)
        rest = sum(new_info[f"reward_{t}"] for t in tp.REWARD_TERMS)
        assert reward == pytest.approx(rest + expected, abs=1e-9)
        obs, info = new, new_info
