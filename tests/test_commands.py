"""The commands run from any directory, with the same names for the same things and their
defaults in ``--help``."""

import re
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


@pytest.mark.parametrize(
    ("main", "argv", "needle"),
    [
        ("benchmarks.throughput", ["--rounds", "0"], r"--rounds: expected a positive integer"),
        ("benchmarks.throughput", ["--budget", "nan"], r"--budget: expected a finite number"),
        ("benchmarks.throughput", ["--budget", "-1"], r"--budget: expected a finite number"),
        ("benchmarks.scripted_speedup", ["--rounds", "0"], r"--rounds: expected a positive"),
        ("benchmarks.step_parts", ["--steps", "-1"], r"--steps: expected a positive integer"),
        ("benchmarks.profile_step", ["--steps", "-5"], r"--steps: expected a positive integer"),
        (
            "agents.planner_starts",
            ["--out", "x.pkl", "--workers", "100000"],
            r"--workers: expected at most 4 x the CPUs",
        ),
        ("benchmarks.planner_shapes", ["--workers", "0"], r"--workers: expected a positive"),
        ("benchmarks.soak", ["--workers", "0"], r"--workers: expected a positive integer"),
    ],
)
def test_bad_numbers_are_usage_errors(main, argv, needle, capsys):
    """Counts, budgets and processes are checked by argparse before any work: exit status 2
    and a message naming the option and the value."""
    import importlib

    with pytest.raises(SystemExit) as info:
        importlib.import_module(main).main(argv)
    assert info.value.code == 2
    assert re.search(needle, capsys.readouterr().err)
