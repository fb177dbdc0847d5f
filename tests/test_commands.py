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


@pytest.mark.parametrize(
    ("main", "argv", "needle"),
    [
        ("benchmarks.edge_probe", ["--shapes", "-1"], r"--shapes: expected a positive integer"),
        ("benchmarks.edge_probe", ["--steps", "-1"], r"--steps: expected a positive integer"),
        ("benchmarks.edge_probe", ["--seed", "-1"], r"--seed: expected a seed >= 0, got '-1'"),
        ("benchmarks.soak", ["--seed", "-1"], r"--seed: expected a seed >= 0, got '-1'"),
        (
            "benchmarks.soak",
            ["--only", "0", "--steps", "-1"],
            r"--steps: expected a positive integer, got '-1'",
        ),
        ("benchmarks.step_times", ["--episodes", "-1"], r"--episodes: expected a positive"),
        ("benchmarks.step_times", ["--steps", "-1"], r"--steps: expected a positive integer"),
        ("benchmarks.blas_variation", ["--episodes", "0"], r"--episodes: expected a positive"),
        ("benchmarks.blas_variation", ["--core-types", "NOPE"], r"--core-types: .*'NOPE'"),
        (
            "benchmarks.step_times",
            ["--replay", "nope", "1", "2"],
            r"--replay: SUITE: expected one of extreme, soak, got 'nope'",
        ),
        (
            "benchmarks.step_times",
            ["--replay", "extreme", "x", "2"],
            r"--replay: SEED: expected an integer, got 'x'",
        ),
        (
            "benchmarks.step_times",
            ["--replay", "soak", "1", "0"],
            r"--replay: STEP: expected a positive integer, got '0'",
        ),
        (
            "benchmarks.blas_variation",
            ["--replay", "nope", "1"],
            r"--replay: SUITE: expected one of default, extreme, got 'nope'",
        ),
        (
            "benchmarks.blas_variation",
            ["--replay", "default", "x"],
            r"--replay: SEED: expected an integer, got 'x'",
        ),
        ("benchmarks.scripted_speedup", ["--base", "nosuchrev"], r"--base: 'nosuchrev' is not a"),
        ("benchmarks.bundled_scenes", ["--timeout", "inf"], r"--timeout: expected a finite"),
        ("benchmarks.bundled_scenes", ["--timeout", "1e10"], r"--timeout: expected at most 1e"),
        ("benchmarks.planner_shapes", ["--timeout", "1e10"], r"--timeout: expected at most 1e"),
        ("benchmarks.planner_shapes", ["--timeout", "0"], r"--timeout: expected a finite"),
    ],
)
def test_bad_values_are_usage_errors(main, argv, needle, capsys):
    """Seeds, counts, suites, core types and revisions are checked by argparse before any
    work: exit status 2 and a message naming the option and the value."""
    _usage_error(main, argv, needle, {}, capsys)


@pytest.fixture
def paths(tmp_path):
    """Paths by name: Latin-1 text, a regular file, a folder, an empty file, an .npz of other
    arrays, and a path that does not exist."""
    import numpy as np

    (tmp_path / "latin1.yml").write_bytes(
        "FrictionlessGrasp-v0: {n_envs: 1} # \xe9\n".encode("latin-1")
    )
    (tmp_path / "file").write_text("x\n")
    (tmp_path / "dir").mkdir()
    (tmp_path / "empty.npz").write_bytes(b"")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    names = ("latin1.yml", "file", "dir", "empty.npz", "other.npz", "missing")
    return {name.split(".")[0]: str(tmp_path / name) for name in names}


def _usage_error(main, argv, needle, paths, capsys):
    """``main(argv)`` of module ``main`` (``{name}`` in ``argv`` and ``needle``: ``paths``)
    exits with status 2 and a message matching ``needle``."""
    import importlib

    argv = [arg.format(**paths) for arg in argv]
    needle = needle.format(**{name: re.escape(path) for name, path in paths.items()})
    with pytest.raises(SystemExit) as info:
        importlib.import_module(main).main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert re.search(needle, err), err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("main", "argv", "needle"),
    [
        (
            "agents.evaluate",
            ["--models", "--readme", "{latin1}", "--results-page", "{dir}/r.md", "--out", "{dir}"],
            r"--readme '{latin1}' is not UTF-8 text",
        ),
        ("agents.evaluate", ["--models", "{missing}"], r"--models: no such directory: '{missing}'"),
        (
            "agents.planner_starts",
            ["--out", "{file}/x.pkl"],
            r"--out: {file}/x.pkl: {file} is not a",
        ),
        ("benchmarks.planner_shapes", ["--out", "{dir}"], r"--out: {dir} is a directory"),
        ("benchmarks.planner_shapes", ["--out", "{file}/x.md"], r"--out: {file}/x.md: {file} is"),
        ("benchmarks.edge_probe", ["--out", "{dir}"], r"--out: {dir} is a directory"),
        ("benchmarks.edge_probe", ["--out", "{file}/a/x.md"], r"--out: {file}/a/x.md: {file} is"),
        (
            "benchmarks.profile_step",
            ["--baseline", "{missing}"],
            r"--baseline: no such file: '{missing}'",
        ),
        ("benchmarks.profile_step", ["--baseline", "{file}"], r"--baseline: '{file}' is not JSON"),
        (
            "agents.scripted",
            ["--scene", "fig13", "--friction-page", "{missing}/f.md"],
            r"--friction-page {missing}/f.md: its folder {missing} does not exist",
        ),
        (
            "agents.scripted",
            ["--scene", "fig13", "--friction-page", "{file}/f.md"],
            r"--friction-page {file}/f.md: its folder {file} is not a directory",
        ),
        ("agents.imitation", ["--data", "{empty}"], r"--data '{empty}' is not an .npz file"),
        ("agents.imitation", ["--data", "{other}"], r"--data '{other}' has no obs, act, round"),
        (
            "agents.train_rllib",
            ["--env", "FrictionlessGrasp-v0", "--num-env-runners", "0", "--config", "{latin1}"],
            r"--config config file '{latin1}' is not UTF-8 text",
        ),
    ],
)
def test_bad_files_are_usage_errors(main, argv, needle, paths, capsys):
    """Files and folders are checked before any work: an output that cannot be written, an
    input that is missing, not UTF-8 or not what it should hold."""
    _usage_error(main, argv, needle, paths, capsys)


@pytest.mark.parametrize(
    ("main", "argv", "needle"),
    [
        ("agents.train_ppo", ["--params", "n_steps:-5"], r"--params 'n_steps:-5': n_steps must"),
        ("agents.train_ppo", ["--params", "batch_size:0"], r"--params 'batch_size:0': batch_size"),
        ("agents.train_ppo", ["--seed", "-1"], r"--seed: expected a seed >= 0, got '-1'"),
        ("agents.train_ppo", ["-f", "{file}"], r"-f {file} exists and is not a directory"),
        ("agents.train_ppo", ["--out", "{file}"], r"--out {file} exists and is not a directory"),
        ("agents.train_ppo", ["--out", "{file}/m"], r"--out {file}/m: {file} is not a directory"),
        ("agents.train_ppo", ["--conf", "{latin1}"], r"--conf config file '{latin1}' is not UTF-8"),
        ("benchmarks.ppo_throughput", ["--entry", "nope"], r"--entry: env id 'nope' is not in"),
    ],
)
def test_bad_training_input_is_a_usage_error(main, argv, needle, paths, capsys):
    """PPO's counts, the seed, the log and model folders, the hyperparameter file and the
    entry are checked before the run folder is made."""
    pytest.importorskip("rl_zoo3")
    _usage_error(main, argv, needle, paths, capsys)


def test_train_rllib_without_ray_says_what_to_install(paths, capsys):
    import importlib.util

    if importlib.util.find_spec("ray") is not None:
        pytest.skip("ray is installed")
    argv = ["--env", "FrictionlessGrasp-v0", "--num-env-runners", "0"]
    needle = r"Ray RLlib is not installed: install the rllib extra"
    _usage_error("agents.train_rllib", argv, needle, paths, capsys)


@pytest.mark.parametrize(
    ("main", "shown"),
    [
        ("benchmarks.planner_shapes", "why it fails where it does, and what a plan costs."),
        ("benchmarks.planner_shapes", "small (3-5 vertices, 0.15-0.6 palm widths wide"),
        ("benchmarks.scripted_speedup", "the page (markdown) (default:"),
    ],
)
def test_help_says_what_options_are(main, shown, capsys):
    import importlib

    with pytest.raises(SystemExit) as info:
        importlib.import_module(main).main(["--help"])
    assert info.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert shown in out and "printed only" not in out


def test_train_ppo_makes_the_model_folder_only_when_it_writes_the_model(tmp_path, monkeypatch):
    """An interrupted run leaves no empty model folder behind (with ``--update-shipped`` it
    would be one in the repository): ``--out`` is checked before training and made after."""
    pytest.importorskip("rl_zoo3")
    import agents.train_ppo as train_ppo

    def interrupted(**kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(train_ppo, "train", interrupted)
    out = tmp_path / "new" / "model"
    with pytest.raises(KeyboardInterrupt):
        train_ppo.main(["--out", str(out), "-f", str(tmp_path / "logs")])
    assert not (tmp_path / "new").exists()
    assert (tmp_path / "logs").is_dir()  # the log folder is the run's, made before it
