"""The commands run from any directory, with the same names for the same things and their
defaults in ``--help``."""

import subprocess
import sys
from pathlib import Path

import pytest

from agents import config

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("module", "shown"),
    [
        ("benchmarks", "--quick"),
        ("benchmarks.soak", "(default: 1000000)"),
        ("benchmarks.memory", "memory.md)"),
    ],
)
def test_benchmarks_run_from_any_directory(module, shown, tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", module, "--help"], cwd=tmp_path, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert f"python -m {module}" in done.stdout and shown in " ".join(done.stdout.split())


def test_soak_runs_as_a_file_too(tmp_path):
    done = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "soak.py"), "--help"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0 and "(default: 0)" in done.stdout, done.stderr


def test_config_files_are_found_from_any_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert config.config_path(config.DEFAULT_CONFIG) == REPO / "configs" / "ppo.yml"
    assert "FrictionlessGrasp-v0" in config.load_config(config.DEFAULT_CONFIG)
    (tmp_path / "configs").mkdir()  # a file of the working directory comes first
    (tmp_path / "configs" / "ppo.yml").write_text("X-v0: {n_timesteps: 1}\n")
    assert list(config.load_config(config.DEFAULT_CONFIG)) == ["X-v0"]


def test_train_ppo_takes_both_spellings():
    pytest.importorskip("rl_zoo3")
    from agents.train_ppo import parser

    long = parser().parse_args(["--conf", "c.yml", "--params", "n_steps:8"])
    short = parser().parse_args(["-conf", "c.yml", "-params", "n_steps:8"])
    assert vars(long) == vars(short)
    assert long.conf_file == "c.yml" and long.hyperparams == {"n_steps": 8}


def test_scene_and_scenes_name_the_scene(capsys):
    from grasp_env.analyze import main

    assert main(["--scenes", "fig13"]) == main(["--scene", "fig13"]) == 0
    assert main(["--scene", "fig14"]) == 2
    assert "error: --scene 'fig14': not a bundled scene" in capsys.readouterr().err
