"""PPO agents: the config file, a tiny training run, and the evaluation command's outputs."""

from __future__ import annotations

import csv
import json
import math
import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

pytest.importorskip("stable_baselines3")

from agents import config as cf
from agents import episodes as ep
from agents import evaluate as ev
from agents import models
from agents import summary as sm
from agents import train_ppo as tp
from agents.planner_agents import PlannerGrip, PlannerResidual
from agents.planner_starts import collect
from agents.wrappers import ApproachShaping, PlannerStarts, TrainingInfo
from grasp_env.envs import ENV_ID, ENV_KWARGS, LIFT_ENV_ID, RANDOM_SHAPES_ENV_ID
from grasp_env.envs.frictionless_grasp import REWARD_TERMS

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "configs" / "ppo.yml"
#: Tiny PPO settings for training runs in tests (short episodes, small rollouts and network).
TINY = {
    "n_steps": 64,
    "batch_size": 32,
    "n_epochs": 2,
    "policy_kwargs": "dict(net_arch=[16])",
    "env_kwargs": {"reward_grip_weight": 1.0, "max_episode_steps": 16},
}


#: Every entry of every SB3 config file: (file, env id).
ENTRIES_OF_FILES = [
    (path, env_id)
    for path in sorted((REPO / "configs").glob("ppo*.yml"))
    for env_id in cf.load_config(path)
]


@pytest.mark.parametrize(
    ("path", "env_id"), ENTRIES_OF_FILES, ids=[f"{p.name}:{e}" for p, e in ENTRIES_OF_FILES]
)
def test_config_entry_builds_its_env(path, env_id, tmp_path, monkeypatch):
    entry = cf.get_entry(cf.load_config(path), env_id)
    for cls, kwargs in cf.wrapper_specs(entry):
        if cls is PlannerStarts:  # the files a command writes first: small ones, in a tmp dir
            monkeypatch.chdir(tmp_path)
            names = kwargs["starts"]
            for name in [names] if isinstance(names, str) else names:
                starts = tmp_path / name
                starts.parent.mkdir(parents=True, exist_ok=True)
                starts.write_bytes(pickle.dumps(collect(1, 0)))
    cf.check_entry(entry)
    kwargs = cf.ppo_kwargs(entry)
    assert set(kwargs).isdisjoint(cf.ENTRY_KEYS)
    assert isinstance(kwargs["policy_kwargs"], dict)
    assert entry["n_envs"] >= 1 and entry["n_timesteps"] > 0


def test_config_is_keyed_by_the_registered_ids():
    raw = yaml.safe_load(CONFIG.read_text())
    assert set(raw) == {ENV_ID, RANDOM_SHAPES_ENV_ID, LIFT_ENV_ID} == set(ENV_KWARGS)
    assert all("env_id" not in entry for entry in raw.values())  # the zoo's format
    config = cf.load_config(CONFIG)
    assert cf.get_entry(config, ENV_ID) == {**config[ENV_ID], "env_id": ENV_ID}
    # The ids fix the task; the entries only re-weight the reward for training.
    for entry in config.values():
        assert all(key.startswith("reward_") for key in entry["env_kwargs"])
    assert set(config[ENV_ID]["env_kwargs"]) == {"reward_grip_weight"}
    (shaping, kwargs), (last, _) = cf.wrapper_specs(config[RANDOM_SHAPES_ENV_ID])
    assert shaping is ApproachShaping and kwargs["touch"] == 0.2
    assert last is TrainingInfo  # outermost, so that the shaping sees the whole info
    for entry in config.values():
        assert [cls for cls, _ in cf.wrapper_specs(entry)][-1] is TrainingInfo
    # The entries share the first one's settings (a YAML merge) unless they say otherwise.
    assert config[RANDOM_SHAPES_ENV_ID]["n_steps"] == config[ENV_ID]["n_steps"] == 512
    assert config[LIFT_ENV_ID]["n_steps"] == 1024 and config[LIFT_ENV_ID]["gamma"] == 0.99
    # The names of the shipped models find their env ids' entries (benchmarks use them).
    assert tp.get_entry(config, "fig13_fingers") == cf.get_entry(config, ENV_ID)


def test_entries_extend_the_lifting_entry():
    """``extends``: the planner agents' files state what differs from the lifting entry of
    configs/ppo.yml, and read as that entry with those keys replaced."""
    lift = cf.load_config(CONFIG)[LIFT_ENV_ID]
    for name in ("ppo_grip.yml", "ppo_handover.yml", "ppo_residual.yml"):
        raw = yaml.safe_load((REPO / "configs" / name).read_text())[LIFT_ENV_ID]
        entry = cf.load_config(REPO / "configs" / name)[LIFT_ENV_ID]
        assert raw.pop("extends") == "ppo.yml"
        assert entry == {**lift, **raw}, name


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x-v0:\n  extends: c.yml\n", "c.yml', a cycle"),
        ("x-v0:\n  extends: d.yml\n", "c.yml', a cycle"),
        ("x-v0:\n  extends: ppo.yml\n", "ppo.yml', without it"),
        ("x-v0:\n  extends: none.yml\n", "none.yml': cannot read it"),
    ],
    ids=["itself", "through-another", "no-such-entry", "no-such-file"],
)
def test_a_bad_extends_is_named(text, message, tmp_path):
    shutil.copy(CONFIG, tmp_path / "ppo.yml")
    (tmp_path / "d.yml").write_text("x-v0:\n  extends: c.yml\n")
    (tmp_path / "c.yml").write_text(text)
    with pytest.raises(ValueError, match=message):
        cf.load_config(tmp_path / "c.yml")


def test_shipped_models_keep_their_set_up():
    for name, env_id in (("fig13_fingers", ENV_ID), ("random_shapes_palm", RANDOM_SHAPES_ENV_ID)):
        _, norm, loaded, entry = models.load_agent(models.MODEL_DIR / name)
        assert loaded == name and entry["env_id"] == env_id and norm is not None
        assert entry["env_kwargs"] == {**ENV_KWARGS[env_id], "reward_grip_weight": 1.0}
    model, norm, _, entry = models.load_agent(models.MODEL_DIR / "lift_palm")
    reward = cf.load_config(CONFIG)[LIFT_ENV_ID]["env_kwargs"]
    assert entry["env_id"] == LIFT_ENV_ID and norm is not None
    assert entry["env_kwargs"] == {**ENV_KWARGS[LIFT_ENV_ID], **reward}
    env = gym.make(LIFT_ENV_ID)
    assert model.observation_space.shape == env.observation_space.shape
    assert ep.ppo_spec(models.MODEL_DIR / "lift_palm").env_kwargs == {
        "palm_control": True,
        "hand_features": True,
    }
    # the paper's set-up trained from perturbed starts: the suites set the start
    _, norm, _, entry = models.load_agent(models.MODEL_DIR / "fig13_perturbed")
    assert entry["env_id"] == ENV_ID and entry["env_kwargs"]["start"] == "random"
    assert ep.ppo_spec(models.MODEL_DIR / "fig13_perturbed").env_kwargs == {}
    spec = ep.ppo_spec(models.MODEL_DIR / "random_shapes_palm")
    assert spec.name == "ppo_random_shapes_palm"
    assert spec.env_kwargs == {"palm_control": True}  # the suites set the start
    assert ep.ppo_spec(models.MODEL_DIR / "fig13_fingers").env_kwargs == {}
    # the residual agent: played through the wrapper its config names, without redraw
    model, norm, _, entry = models.load_agent(models.MODEL_DIR / "lift_residual")
    assert entry["env_id"] == LIFT_ENV_ID and norm is not None
    assert model.observation_space.shape == (env.observation_space.shape[0] + 5,)
    spec = ep.ppo_spec(models.MODEL_DIR / "lift_residual")
    assert spec.wrapper == (PlannerResidual, {"scale": 0.25, "redraw": False})
    assert spec.env_kwargs == {"palm_control": True, "hand_features": True}
    # the grip agent: the planner's plan, then palm turns observing the turn probes
    model, norm, _, entry = models.load_agent(models.MODEL_DIR / "lift_grip")
    assert entry["env_id"] == LIFT_ENV_ID and norm is not None
    assert model.observation_space.shape == (env.observation_space.shape[0] + 13,)
    assert model.action_space.shape == (3,)
    spec = ep.ppo_spec(models.MODEL_DIR / "lift_grip")
    assert spec.wrapper[0] is PlannerGrip and not spec.wrapper[1]["redraw"]
    assert spec.wrapper[1]["palm_only"] and spec.wrapper[1]["probe_turns"]


def test_the_shipped_grip_agent_lightens_the_planners_grip():
    # the first held-out lifting shape: the planner's grasp holds the object at 3.9 W
    seed = ep.HELDOUT_SEED
    planner = ep.run_episode(
        ep.PolicySpec("scripted", "scripted", ep.SCRIPTED_KWARGS), "lift", "", seed, None
    )
    agent = ep.run_episode(ep.ppo_spec(models.MODEL_DIR / "lift_grip"), "lift", "", seed, None)
    assert planner.success and agent.success and not agent.dropped
    assert planner.steps_to_closure == agent.steps_to_closure  # the planner's lifting
    assert agent.grip_W < planner.grip_W - 1.0


@pytest.mark.parametrize("k", [0, 1])
def test_the_planner_in_place_lifts_where_lifting_from_the_first_placement_does(k):
    """``scripted_in_place`` on the ``lift`` suite succeeds exactly where the planner's
    lifting phase, run directly from the first placement, reaches form closure: on shape 0
    it does not (the full planner re-places the hand and lifts it), on shape 1 it does."""
    from grasp_env.planning.grasp import first_placement
    from grasp_env.planning.lifting import lift
    from grasp_env.simulator import Simulator

    seed = ep.HELDOUT_SEED + k
    env = gym.make(LIFT_ENV_ID, **ep.LIFT_KWARGS)
    env.reset(seed=seed)
    sim = Simulator(env.unwrapped.scene)
    lifts_in_place = lift(sim, first_placement(sim)[0], 0.02).status == "form_closure"
    assert lifts_in_place == (k == 1)
    in_place = ep.PolicySpec("scripted_in_place", "scripted_in_place", ep.SCRIPTED_KWARGS)
    played = ep.run_episode(in_place, "lift", "", seed, None)
    assert played.success == lifts_in_place and not played.error
    planner = ep.PolicySpec("scripted", "scripted", ep.SCRIPTED_KWARGS)
    assert ep.run_episode(planner, "lift", "", seed, None).success


def test_the_planner_in_place_is_a_row_on_request(tmp_path, capsys):
    argv = ["--models", "--scenes", "fig13", "--max-steps", "2", "--episodes", "1"]
    ev.main([*argv, "--out", str(tmp_path / "without")])
    assert "scripted_in_place" not in capsys.readouterr().out
    ev.main([*argv, "--planner-in-place", "--out", str(tmp_path / "with")])
    printed = capsys.readouterr().out
    assert "| heldout | scripted_in_place | planner | 1 |" in printed
    assert "| heldout | scripted | planner | 1 |" in printed


def test_what_rllib_and_evaluation_import_needs_neither_sb3_nor_the_zoo():
    """RLlib's env runners and ``agents.evaluate`` of RLlib checkpoints run where neither is
    installed (the rllib extra)."""
    code = (
        "import sys, agents.config, agents.wrappers, agents.train_rllib, agents.evaluate; "
        "print(sorted(m for m in ('stable_baselines3', 'rl_zoo3', 'torch') if m in sys.modules))"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "[]"


def _write(path: Path, text: str) -> str:
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--env", "no_such_entry"], "'no_such_entry' is not in the config"),
        (["--conf-file", "missing.yml"], "'missing.yml': cannot read it"),
        (["--n-timesteps", "-5"], "'-5'"),
        (["--max-minutes", "nan"], "'nan'"),
        (["--hyperparams", "n_steps"], "expected key:value, got 'n_steps'"),
        (["--hyperparams", "learning_rate:exp_3"], "learning_rate 'exp_3'"),
        (["--hyperparams", "policy_kwargs:dict("], "policy_kwargs 'dict('"),
        (["--out", str(models.MODEL_DIR / "fig13_fingers")], "already holds a model"),
        (["--out", "x", "--update-shipped"], "not allowed with argument"),
        (["--conf-file", "<yaml>FrictionlessGrasp-v0:\n  n_envs: 2\n   bad: [\n"], "(line 3"),
        (["--conf-file", "<yaml>- a list\n"], "expected a mapping of env ids"),
        (
            ["--conf-file", "<yaml>FrictionlessGrasp-v0:\n  n_timesteps: 8\n  learnin_rate: 1\n"],
            "unknown key(s) learnin_rate",
        ),
        (
            ["--conf-file", "<yaml>FrictionlessGrasp-v0:\n  n_timesteps: 8\n  n_envs: 0\n"],
            "n_envs must be a positive integer",
        ),
    ],
    ids=[
        "unknown-env",
        "missing-file",
        "negative-steps",
        "nan-minutes",
        "override-without-colon",
        "bad-schedule",
        "bad-expression",
        "out-holds-a-model",
        "out-and-update-shipped",
        "malformed-yaml",
        "not-a-mapping",
        "unknown-key",
        "zero-envs",
    ],
)
def test_train_command_names_the_bad_value_in_one_line(argv, message, tmp_path, capsys):
    argv = [
        _write(tmp_path / "c.yml", a[len("<yaml>") :]) if a.startswith("<yaml>") else a
        for a in argv
    ]
    argv += ["-f", str(tmp_path / "runs")]
    with pytest.raises(SystemExit) as exit_info:
        tp.main(argv)
    assert exit_info.value.code == 2
    out, err = capsys.readouterr()
    assert message in err and not out
    assert err.count("\n") == 1 and err.startswith("python -m agents.train_ppo: error:")
    assert not (tmp_path / "runs").exists()  # caught before any work


def test_help_shows_the_defaults(capsys):
    with pytest.raises(SystemExit):
        tp.main(["--help"])
    out = " ".join(capsys.readouterr().out.split())  # wrapping depends on the terminal
    assert "(default: FrictionlessGrasp-v0)" in out and "(default: configs/ppo.yml)" in out
    assert "(default: runs)" in out and "(default: 10000)" in out
    assert "``" not in out and "(default: None)" not in out


def test_bad_env_kwarg_is_named(tmp_path):
    config = tmp_path / "bad.yml"
    entry = {"n_timesteps": 8, "env_kwargs": {"start": "sideways"}}
    config.write_text(yaml.safe_dump({ENV_ID: entry}))
    with pytest.raises(ValueError, match=r"entry 'FrictionlessGrasp-v0'.*sideways"):
        cf.check_entry(cf.get_entry(cf.load_config(config), ENV_ID))


def test_unknown_wrapper_is_named():
    with pytest.raises(ValueError, match=r"'my\.Wrapper'"):
        cf.wrapper_specs({"env_wrapper": "my.Wrapper"})


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A PPO model trained for 256 steps on short fig13 episodes (the shipped entry's
    settings with tiny rollouts), written to a model directory ``tiny``."""
    pytest.importorskip("rl_zoo3")
    tmp = tmp_path_factory.mktemp("ppo")
    _train_tiny(tmp, "tiny", TINY, 256, save_freq=128)
    return tmp / "tiny"


def _train_tiny(folder: Path, name: str, hyperparams: dict, steps: int, save_freq: int) -> None:
    """A tiny fig13 run into ``folder/runs``, its model directory ``folder/name``."""
    tp.train(
        ENV_ID,
        conf_file=CONFIG,
        hyperparams=hyperparams,
        n_timesteps=steps,
        log_folder=folder / "runs",
        out=folder / name,
        eval_freq=128,
        eval_episodes=1,
        save_freq=save_freq,
        print_freq=0,
    )


def test_tiny_training_saves_and_reloads(trained):
    for name in ("model.zip", "vecnormalize.pkl", "config.yml", "train_stats.json"):
        assert (trained / name).is_file(), name
    stats = json.loads((trained / "train_stats.json").read_text())
    assert stats["timesteps"] == 256 and stats["env_steps_per_s"] > 0
    run = Path(stats["run"])
    assert run == trained.parent / "runs" / "ppo" / f"{ENV_ID}_1"
    assert (run / "train_stats.json").is_file() and (run / f"{ENV_ID}.zip").is_file()
    assert list(run.glob("rl_model_*_steps.zip")) and list(run.glob("rl_model_vecnormalize_*"))
    assert (run / "evaluations.npz").is_file()
    header = (run / "0.monitor.csv").read_text().splitlines()[1].split(",")
    assert "is_success" in header
    config = yaml.safe_load((trained / "config.yml").read_text())
    assert list(config) == [ENV_ID] and config[ENV_ID]["n_timesteps"] == 256
    assert config[ENV_ID]["n_steps"] == 64  # the overrides as used

    # RewardTermsCallback logged the episode sums of the reward terms.
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    (events,) = (run / "tb").iterdir()
    tags = EventAccumulator(str(events)).Reload().Tags()["scalars"]
    assert {"rollout/ep_reward_lift_mean", "rollout/ep_reward_grip_mean"} <= set(tags)

    for directory, expected in ((trained, "tiny"), (run, run.name)):
        model, norm, name, entry = models.load_agent(directory)
        assert name == expected and norm is not None and not norm.training
        assert entry["env_id"] == ENV_ID and entry["env_kwargs"]["max_episode_steps"] == 16
        env = gym.make(entry["env_id"], **entry["env_kwargs"])
        obs, _ = env.reset(seed=0)
        action, _ = model.predict(norm.normalize_obs(obs), deterministic=True)
        assert env.action_space.contains(action.astype(np.float32))
        env.close()


def _tiny_argv(tmp_path: Path, *extra: str) -> list[str]:
    params = [f"{k}:{v!r}" if not isinstance(v, str) else f"{k}:{v}" for k, v in TINY.items()]
    return [
        "--conf-file",
        str(CONFIG),
        "-n",
        "128",
        "--eval-freq",
        "0",
        "--save-freq",
        "0",
        "--print-freq",
        "64",
        "--hyperparams",
        *params,
        *extra,
    ]


def _shipped() -> dict[str, bytes]:
    return {str(p): p.read_bytes() for p in sorted(models.MODEL_DIR.glob("*/*"))}


def test_training_from_a_trained_agent_starts_from_its_weights_and_statistics(trained, tmp_path):
    """``trained_agent``: with a learning rate of 0 the weights stay the loaded model's, bit
    for bit, and the observation statistics go on from its (a new policy or new statistics
    would show)."""
    import torch

    start, start_norm, _, _ = models.load_agent(trained)
    tp.train(
        ENV_ID,
        conf_file=CONFIG,
        hyperparams={**TINY, "learning_rate": 0.0},
        n_timesteps=128,
        log_folder=tmp_path / "runs",
        out=tmp_path / "again",
        eval_freq=0,
        save_freq=0,
        print_freq=0,
        trained_agent=trained,
    )
    model, norm, _, _ = models.load_agent(tmp_path / "again")
    weights = model.policy.state_dict()
    assert weights.keys() == start.policy.state_dict().keys()
    for name, value in start.policy.state_dict().items():
        torch.testing.assert_close(weights[name], value, rtol=0.0, atol=0.0, msg=name)
    assert norm.obs_rms.count >= start_norm.obs_rms.count + 128
    stats = json.loads((tmp_path / "again" / "train_stats.json").read_text())
    assert stats["trained_agent"] == str(trained)  # where the run's steps started from


def test_training_writes_to_runs_and_leaves_the_shipped_models(tmp_path, monkeypatch, capsys):
    pytest.importorskip("rl_zoo3")
    shipped = _shipped()
    monkeypatch.chdir(tmp_path)
    tp.main(_tiny_argv(tmp_path))
    out = capsys.readouterr().out
    run = tmp_path / "runs" / "ppo" / f"{ENV_ID}_1"
    assert (run / f"{ENV_ID}.zip").is_file() and (run / ENV_ID / "vecnormalize.pkl").is_file()
    assert "64/128 steps (50%)" in out and "128/128 steps (100%)" in out  # progress lines
    assert f"run runs/ppo/{ENV_ID}_1: 128 steps" in out
    assert _shipped() == shipped
    # A second run gets a folder of its own.
    tp.main(_tiny_argv(tmp_path, "--print-freq", "0"))
    assert (tmp_path / "runs" / "ppo" / f"{ENV_ID}_2" / f"{ENV_ID}.zip").is_file()
    assert (run / f"{ENV_ID}.zip").is_file() and _shipped() == shipped


def test_update_shipped_writes_the_model_directory(tmp_path, monkeypatch):
    pytest.importorskip("rl_zoo3")
    shipped = tmp_path / "models"
    monkeypatch.setattr(tp, "MODEL_DIR", shipped)
    tp.main(_tiny_argv(tmp_path, "-f", str(tmp_path / "runs"), "--update-shipped"))
    _, norm, name, entry = models.load_agent(shipped / "fig13_fingers")
    assert name == "fig13_fingers" and entry["env_id"] == ENV_ID and norm is not None
    assert sorted(p.name for p in (shipped / "fig13_fingers").iterdir()) == [
        "config.yml",
        "model.zip",
        "train_stats.json",
        "vecnormalize.pkl",
    ]


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
    assert "| heldout | random | network | 2 |" in printed and "ppo_tiny" in printed
    for name in ("episodes.csv", "summary.csv", "summary.md", "summary.png"):
        assert (out / name).stat().st_size > 0, name
    for policy in ("ppo_tiny", "random"):
        assert (out / f"{policy}.gif").stat().st_size > 0, policy
    rows = (out / "episodes.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * (1 + 2)  # header + 2 policies x (1 scene + 2 shapes)


def test_sampled_play_replays_each_episode_and_is_its_own_row(trained, tmp_path, capsys):
    """A sampled model is a network-only row of its own; the same episode seed replays the
    same episode, whatever ran before it in the process; a path that is no model is refused
    by name."""
    spec = ep.ppo_spec(trained, sampled=True)
    assert (spec.name, spec.test_time, spec.sampled) == ("ppo_tiny_sampled", "network", True)
    first = ep.run_episode(spec, "heldout", "random", ep.HELDOUT_SEED, 6)
    ep.run_episode(spec, "heldout", "random", ep.HELDOUT_SEED + 1, 6)
    assert ep.run_episode(spec, "heldout", "random", ep.HELDOUT_SEED, 6) == first
    with pytest.raises(ValueError, match="only a 'ppo' model plays sampled"):
        ep.PolicySpec("random", "random", sampled=True)
    out = tmp_path / "eval"
    argv = ["--models", "--no-scripted", "--scenes", "fig13", "--max-steps", "2"]
    ev.main([*argv, "--episodes", "1", "--sampled", str(trained), "--out", str(out)])
    printed = capsys.readouterr().out
    assert "| heldout | ppo_tiny_sampled | network | 1 |" in printed
    with pytest.raises(SystemExit):
        ev.main([*argv, "--sampled", str(tmp_path / "nothing"), "--out", str(out)])
    assert "nothing" in capsys.readouterr().err


def test_sampled_actions_follow_the_policys_distribution():
    """Sampled play draws from the policy's Gaussian, clipped to the action bounds: each
    coordinate's draws against that distribution (Kolmogorov-Smirnov, computed apart from
    SB3 from the network's mean and log standard deviation), and the deterministic action is
    the mean."""
    import torch
    from scipy import stats

    from agents.models import network_action, seed_sampling

    model, norm, _, entry = models.load_agent(models.MODEL_DIR / "scene_starts")
    env = gym.make(entry["env_id"], **entry["env_kwargs"])
    obs, _ = env.reset(seed=5)
    x = torch.as_tensor(norm.normalize_obs(obs)[None], dtype=torch.float32)
    with torch.no_grad():
        features = model.policy.extract_features(x, model.policy.pi_features_extractor)
        mean = model.policy.action_net(model.policy.mlp_extractor.forward_actor(features))[0]
    mean, std = mean.numpy(), torch.exp(model.policy.log_std).detach().numpy()
    low, high = env.action_space.low, env.action_space.high
    np.testing.assert_allclose(
        network_action(model, norm, obs), np.clip(mean, low, high), rtol=1e-6, atol=1e-6
    )
    seed_sampling(0)
    draws = np.array([network_action(model, norm, obs, sampled=True) for _ in range(2000)])
    tested = 0
    for j in range(len(mean)):
        a, b = (low[j] - mean[j]) / std[j], (high[j] - mean[j]) / std[j]
        for share, expected in (
            (np.mean(draws[:, j] <= low[j]), stats.norm.cdf(a)),  # clipped to each bound
            (np.mean(draws[:, j] >= high[j]), stats.norm.sf(b)),
        ):
            assert abs(share - expected) < 4 * np.sqrt(expected / len(draws)) + 1e-3, j
        inside = draws[:, j][(draws[:, j] > low[j]) & (draws[:, j] < high[j])]
        if len(inside) >= 200:
            truncated = stats.truncnorm(a, b, loc=mean[j], scale=std[j])
            assert stats.kstest(inside, truncated.cdf).pvalue > 1e-3, j
            tested += 1
    assert tested >= 2  # the start has coordinates inside the bounds (the fingers' are not)


@pytest.mark.parametrize(
    ("where", "message"),
    [
        (lambda tmp: tmp / "file", "exists and is not a directory"),
        (lambda tmp: tmp / "file" / "sub", "cannot be created"),
        (lambda tmp: Path("/proc/x"), "cannot be created"),
    ],
    ids=["existing-file", "under-a-file", "proc"],
)
def test_evaluation_refuses_a_bad_out_before_any_episode(
    where, message, tmp_path, capsys, monkeypatch
):
    (tmp_path / "file").write_text("")
    out = where(tmp_path)
    monkeypatch.setattr(ev, "evaluate", lambda *a, **k: pytest.fail("episodes ran"))
    with pytest.raises(SystemExit) as info:
        ev.main(["--models", "--scenes", "fig13", "--out", str(out)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"error: --out {out} {message}" in err and "Traceback" not in err


def test_evaluation_refuses_more_workers_than_its_bound(capsys, monkeypatch):
    monkeypatch.setattr(ev, "evaluate", lambda *a, **k: pytest.fail("episodes ran"))
    monkeypatch.setenv("COLUMNS", "200")  # --help on one line per option
    with pytest.raises(SystemExit) as info:
        ev.main(["--models", "--workers", str(ev.MAX_WORKERS + 1)])
    assert info.value.code == 2
    assert (
        f"error: argument --workers: expected at most 4 x the CPUs = {ev.MAX_WORKERS} "
        f"processes, got '{ev.MAX_WORKERS + 1}'" in capsys.readouterr().err
    )
    assert ev.MAX_WORKERS == 4 * (os.cpu_count() or 1)
    with pytest.raises(SystemExit):
        ev.main(["--help"])
    assert f"at most 4 x the CPUs = {ev.MAX_WORKERS}" in capsys.readouterr().out


def test_policies_meet_the_same_heldout_shapes():
    vertices = slice(13, 13 + 2 * 12)  # object vertices in the observation
    obs = [
        ep.make_env(ep.PolicySpec(kind, kind, kwargs), ep.HELDOUT_KWARGS, 4).reset(
            seed=ep.HELDOUT_SEED
        )[0][vertices]
        for kind, kwargs in (("scripted", ep.SCRIPTED_KWARGS), ("random", ep.RANDOM_KWARGS))
    ]
    assert np.array_equal(obs[0], obs[1]) and np.any(obs[0] != 0)


def test_policies_meet_the_same_perturbed_fig13_starts():
    # Every policy's env starts the perturbed suite's episode from the same hand, drawn by the
    # seed: the pre-liftoff placement perturbed, so it differs between seeds.
    hands = {}
    for kind, kwargs in (("scripted", ep.SCRIPTED_KWARGS), ("random", ep.RANDOM_KWARGS)):
        env = ep.make_env(ep.PolicySpec(kind, kind, kwargs), ep.PERTURBED_KWARGS, 4)
        hands[kind] = []
        for k in range(2):
            env.reset(seed=ep.HELDOUT_SEED + k)
            hands[kind].append(env.unwrapped.state.hand.copy())
        env.close()
    np.testing.assert_array_equal(hands["scripted"], hands["random"])
    assert np.abs(hands["random"][0] - hands["random"][1]).max() > 1e-6


def test_policies_meet_the_same_lift_starts():
    """The lifting suite starts every policy at the same placement of the same shape, whatever
    its own set-up (the scripted policy's palm control, the random policy's fingers only, a
    lifting model's hand features)."""
    hands = {}
    set_ups = {
        "scripted": ep.SCRIPTED_KWARGS,
        "random": ep.RANDOM_KWARGS,
        "ppo": {"palm_control": True, "hand_features": True, "start": "scene"},
    }
    for kind, kwargs in set_ups.items():
        env = ep.make_env(ep.PolicySpec(kind, kind, kwargs), ep.LIFT_KWARGS, 4)
        env.reset(seed=ep.HELDOUT_SEED)
        hands[kind] = (env.unwrapped.state.hand.copy(), env.unwrapped.state.object_pose.copy())
        env.close()
    for kind in ("random", "ppo"):
        np.testing.assert_array_equal(hands[kind][0], hands["scripted"][0])
        np.testing.assert_array_equal(hands[kind][1], hands["scripted"][1])


def test_wide_suite_draws_from_the_wide_ranges():
    # Over 40 held-out seeds the wide suite's shapes use vertex counts beyond the default 8
    # and stay within 3-12; the default suite's never exceed 8.
    counts = {}
    for suite, kwargs in ep.SHAPE_SUITES.items():
        env = ep.make_env(ep.PolicySpec("random", "random", ep.RANDOM_KWARGS), kwargs, 4)
        counts[suite] = []
        for k in range(40):
            env.reset(seed=ep.HELDOUT_SEED + k)
            counts[suite].append(len(env.unwrapped.scene.object.vertices_B))
        env.close()
    assert 3 <= min(counts["wide"]) and max(counts["wide"]) <= 12
    assert max(counts["wide"]) > 8 and max(counts["heldout"]) <= 8


@pytest.mark.parametrize(
    ("k", "n", "low", "high"),
    [(0, 10, 0.0, 0.2775), (10, 10, 0.7225, 1.0), (5, 10, 0.2366, 0.7634)],
    ids=["none", "all", "half"],
)
def test_wilson_interval_matches_published_values(k, n, low, high):
    lo, hi = sm.wilson(k, n)
    assert lo == pytest.approx(low, abs=1e-4) and hi == pytest.approx(high, abs=1e-4)


def test_bootstrap_interval_brackets_the_mean():
    lo, hi = sm.bootstrap_mean([1.0, 2.0, 3.0, 4.0])
    assert lo < 2.5 < hi
    assert sm.bootstrap_mean([2.0, 2.0]) == (2.0, 2.0)
    assert all(math.isnan(x) for x in sm.bootstrap_mean([]))


def test_approach_shaping_is_potential_based():
    entry = cf.get_entry(cf.load_config(CONFIG), RANDOM_SHAPES_ENV_ID)
    (cls, kwargs), _ = cf.wrapper_specs(entry)
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
        rest = sum(new_info[f"reward_{t}"] for t in REWARD_TERMS)
        assert reward == pytest.approx(rest + expected, abs=1e-9)
        obs, info = new, new_info


def test_training_info_keeps_what_training_reads():
    """The same episode with and without the wrapper: the same observations and rewards, and
    of each info exactly ``is_success``, the reward terms and ``sim_error``, unchanged."""
    entry = cf.get_entry(cf.load_config(CONFIG), RANDOM_SHAPES_ENV_ID)
    make = [lambda: gym.make(entry["env_id"], **entry["env_kwargs"])] * 2
    full, kept = make[0](), TrainingInfo(make[1]())
    full.reset(seed=5), kept.reset(seed=5)
    actions = np.random.default_rng(0).uniform(-1, 1, (30, 5)).astype(np.float32)
    for action in actions:
        *out, info = full.step(action)
        *out_kept, info_kept = kept.step(action)
        assert np.array_equal(out[0], out_kept[0]) and out[1:] == out_kept[1:]
        expected = {k: v for k, v in info.items() if k.startswith("reward_")}
        expected["is_success"] = info["is_success"]
        assert info_kept == expected
    # a step that ends in a simulator error (a work limit of one pose solve) passes its
    # message on
    sim = kept.unwrapped.simulator
    sim.model = sim.model._replace(max_solves=1)
    terminated = False
    for action in actions:
        *_, terminated, _, info_kept = kept.step(action)
        if terminated:
            break
    assert terminated and info_kept["sim_error"].startswith("WorkLimitError")
    assert set(info_kept) == {"is_success", "sim_error", *(f"reward_{t}" for t in REWARD_TERMS)}


def test_training_info_passes_on_the_monitors_episode():
    """As the zoo wraps (``env_wrapper`` outside the Monitor): the episode's last info keeps
    the Monitor's ``episode`` record, by which SB3 counts episodes (its evaluation would
    otherwise never end) and logs their returns."""
    from stable_baselines3.common.monitor import Monitor

    env = TrainingInfo(
        Monitor(gym.make(ENV_ID, max_episode_steps=3), info_keywords=("is_success",))
    )
    env.reset(seed=0)
    for k in range(3):
        *_, terminated, truncated, info = env.step(np.array([1.0, 1.0], np.float32))
        assert ("episode" in info) == (terminated or truncated) == (k == 2)
    assert info["episode"]["l"] == 3 and info["episode"]["is_success"] == info["is_success"]


def test_checkpoint_steps_read_from_the_zoos_file_names():
    from agents.models import checkpoint_steps, norm_file_of

    assert checkpoint_steps(Path("run/rl_model_2000000_steps.zip")) == 2_000_000
    assert checkpoint_steps(Path(f"run/{ENV_ID}.zip")) is None
    assert checkpoint_steps(Path("run/rl_model_vecnormalize_2000000_steps.pkl")) is None
    assert norm_file_of(Path("run/rl_model_64_steps.zip")) == Path(
        "run/rl_model_vecnormalize_64_steps.pkl"
    )


def test_learning_curves_of_a_run(trained, tmp_path, capsys):
    """The tiny run's checkpoints (every 128 steps) played on validation shapes, and its
    training episodes binned; a folder without checkpoints is refused by name."""
    from agents import learning_curves as lc

    (run,) = (trained.parent / "runs" / "ppo").glob(f"{ENV_ID}_*")
    assert [s for s, _ in lc.checkpoints(run, 128)] == [128, 256]
    lc.main([str(run), "--shapes", "2", "--every", "128", "--bin", "100", "--out", str(tmp_path)])
    rows = list(csv.DictReader(open(tmp_path / "learning_curves.csv")))
    assert [int(r["steps"]) for r in rows] == [128, 256]
    assert all(float(r["success_rate"]) in (0.0, 0.5, 1.0) for r in rows)
    assert (tmp_path / "learning_curves.png").stat().st_size > 0
    # checkpoint selection: the best row's model file, its statistics and steps
    lc.main([str(run), "--shapes", "2", "--every", "128", "--out", str(tmp_path / "sel"),
             "--best-out", str(tmp_path / "sel" / "best")])  # fmt: skip
    rows = list(csv.DictReader(open(tmp_path / "sel" / "learning_curves.csv")))
    top = max(float(r["success_rate"]) for r in rows)
    kept = [r for r in rows if float(r["success_rate"]) == top]
    grips = [math.inf if r["grip_W_mean"] == "nan" else float(r["grip_W_mean"]) for r in kept]
    chosen = kept[int(np.argmin(grips))]  # first of the lowest grip: the fewest steps
    model_file = Path(chosen["model"])
    assert (tmp_path / "sel" / "best" / "model.zip").read_bytes() == model_file.read_bytes()
    norm_file = model_file.with_name(f"rl_model_vecnormalize_{chosen['steps']}_steps.pkl")
    assert (tmp_path / "sel" / "best" / "vecnormalize.pkl").read_bytes() == norm_file.read_bytes()
    stats = json.loads((tmp_path / "sel" / "best" / "train_stats.json").read_text())
    assert stats["timesteps"] == int(chosen["steps"]) and stats["checkpoint"] == model_file.name
    (entry,) = yaml.safe_load((tmp_path / "sel" / "best" / "config.yml").read_text()).values()
    assert entry["n_timesteps"] == int(chosen["steps"])
    models.load_agent(tmp_path / "sel" / "best")  # a model directory like any other
    kept_model = (tmp_path / "sel" / "best" / "model.zip").read_bytes()
    with pytest.raises(SystemExit):  # a folder holding a model is never overwritten
        lc.main([str(run), "--shapes", "2", "--every", "128", "--out", str(tmp_path / "sel2"),
                 "--best-out", str(tmp_path / "sel" / "best")])  # fmt: skip
    assert "already holds a model.zip" in capsys.readouterr().err
    assert (tmp_path / "sel" / "best" / "model.zip").read_bytes() == kept_model
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit):
        lc.main([str(run), "--out", str(tmp_path / "file")])
    assert "--out" in capsys.readouterr().err
    unfinished = tmp_path / "unfinished" / run.name
    shutil.copytree(run, unfinished, ignore=shutil.ignore_patterns("train_stats.json"))
    with pytest.raises(SystemExit):
        lc.main([str(unfinished), "--best-out", str(tmp_path / "b2"), "--out", str(tmp_path)])
    assert "has not finished" in capsys.readouterr().err
    for again in ("sampled", "sampled_again"):  # sampled play replays from the seeds
        lc.main([str(run), "--shapes", "2", "--every", "256", "--sampled", "--out",
                 str(tmp_path / again)])  # fmt: skip
    assert (tmp_path / "sampled" / "learning_curves.csv").read_text() == (
        tmp_path / "sampled_again" / "learning_curves.csv"
    ).read_text()
    training = lc.training_success(run, 100)
    assert [edge for edge, _ in training] == [100, 200][: len(training)]
    with pytest.raises(SystemExit):
        lc.main([str(tmp_path / "missing"), "--out", str(tmp_path / "x")])
    assert "no such folder" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        lc.main([str(tmp_path), "--out", str(tmp_path / "x")])
    assert "is not a zoo run folder" in capsys.readouterr().err
    early = tmp_path / "early" / run.name  # a run that has saved no checkpoint yet
    shutil.copytree(run, early, ignore=shutil.ignore_patterns("rl_model_*"))
    with pytest.raises(SystemExit):
        lc.main([str(early), "--out", str(tmp_path / "x")])
    assert "no checkpoints yet" in (err := capsys.readouterr().err) and "--save-freq" in err
    # seeds run side by side in log folders of their own: same folder name, labelled by seed
    twin = tmp_path / "seed1" / run.name
    shutil.copytree(run, twin)
    stats = json.loads((twin / "train_stats.json").read_text())
    (twin / "train_stats.json").write_text(json.dumps({**stats, "seed": stats["seed"] + 1}))
    out = tmp_path / "two"
    lc.main([str(run), str(twin), "--shapes", "1", "--every", "256", "--out", str(out)])
    rows = list(csv.DictReader(open(out / "learning_curves.csv")))
    seed = stats["seed"]
    assert [(r["run"], int(r["steps"])) for r in rows] == [
        (f"seed {seed}", 256),
        (f"seed {seed + 1}", 256),
    ]
    # no seeds to tell them apart: the log folders do, without the zoo's folders
    a, b = (tmp_path / name / "ppo" / run.name for name in ("a", "b"))
    assert lc.run_labels([a, b]) == ["a", "b"]
    with pytest.raises(SystemExit):
        lc.main([str(run), str(run), "--out", str(tmp_path / "y")])
    assert "given twice" in capsys.readouterr().err


def test_evaluation_env_gets_the_entrys_task_kwargs(tmp_path):
    """An entry whose env_kwargs change the task (here the observation's vertex padding)
    trains and evaluates on that task: the evaluation env is made with the same kwargs, less
    the reward weights (it reports the env's own return)."""
    pytest.importorskip("rl_zoo3")
    env_kwargs = {"reward_grip_weight": 1.0, "max_episode_steps": 16, "max_vertices": 8}
    _train_tiny(tmp_path, "model", {**TINY, "env_kwargs": env_kwargs}, 128, save_freq=0)
    model, _, _, entry = models.load_agent(tmp_path / "model")
    assert entry["env_kwargs"]["max_vertices"] == 8
    assert model.observation_space.shape == (24 + 3 * 8,)
    (run,) = (tmp_path / "runs" / "ppo").iterdir()
    assert len(np.load(run / "evaluations.npz")["results"]) == 1  # the evaluation ran


def test_a_model_trained_with_uncertainty_meets_every_level_of_a_sweep(tmp_path):
    """The sweep sets ``uncertainty`` and ``friction``; a model's training values of them do
    not leak into its evaluation env (at the sweep's level 0 it plays the exact object)."""
    model_dir = tmp_path / "lift_uncertain"
    shutil.copytree(models.MODEL_DIR / "lift_palm", model_dir)
    config = yaml.safe_load((model_dir / "config.yml").read_text())
    config[LIFT_ENV_ID]["env_kwargs"] |= {"uncertainty": 0.02, "friction": 0.1}
    (model_dir / "config.yml").write_text(yaml.safe_dump(config))
    _, _, _, entry = models.load_agent(model_dir)
    assert entry["env_kwargs"]["uncertainty"] == 0.02  # the model did train with it
    spec = ep.ppo_spec(model_dir)
    assert spec.env_kwargs == {"palm_control": True, "hand_features": True}
    exact = ep.run_episode(spec, "lift", "", 1_000_000, 5)
    uncertain = ep.run_episode(spec, "lift", "", 1_000_000, 5, uncertainty=0.02)
    assert exact.uncertainty == 0.0 and uncertain.uncertainty == 0.02
    assert not exact.error and not uncertain.error
