"""Learning curves of PPO runs: success and ``y*`` against env steps, mean and spread over
seeds.

    python -m agents.learning_curves RUN [RUN ...] [--shapes 20] [--every 250000]
        [--workers 2] [--sampled] [--out runs/learning_curves] [--best-out DIR]

Each ``RUN`` is a zoo run folder of ``agents.train_ppo`` (``<log folder>/ppo/<env id>_<n>``,
one per seed, all of one env id). Two curves per run:

* **training**: the share of the Monitor's episodes (every training env) that ended in
  success, in bins of ``--bin`` env steps: what the exploring policy achieved;
* **checkpoints**: each checkpoint the run saved (``rl_model_<steps>_steps.zip`` with its
  ``VecNormalize`` statistics) at a multiple of ``--every`` steps, and the final model, played
  deterministically (with ``--sampled``, actions drawn from the policy's distribution,
  seeded with each episode's seed) on ``--shapes`` validation episodes of the run's env id (seeds
  ``VALIDATION_SEED + k``: neither the training seeds nor the held-out ones of
  ``agents.evaluate``): success rate and mean ``y* / W`` over the successes (those whose
  torque limits admit no grip, ``y* = inf``, left out).

Writes ``learning_curves.png`` (three panels: success and ``y*/W`` against env steps, the
mean over seeds with the band from the lowest to the highest seed; each run's success
against its wall time, from when each model file was written) and ``learning_curves.csv``
(one row per run and checkpoint) into ``--out``; with ``--best-out DIR`` also the model
directory of the best model played (:func:`best`: checkpoint selection on the validation
shapes). See ``docs/training.md``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np
import yaml

import grasp_env  # noqa: F401  (registers the env ids)
from agents.models import (
    checkpoint_steps,
    export_checkpoint,
    load_checkpoint,
    network_action,
    read_model_dir,
    seed_sampling,
)
from agents.planner_base import planner_wrapper
from grasp_env.cli import HelpFormatter, out_dir_problem, positive_int, workers

#: First seed of the validation episodes: apart from training (small seeds) and from the
#: held-out suites of ``agents.evaluate`` (1,000,000 on).
VALIDATION_SEED = 2_000_000


def checkpoints(run: Path, every: int) -> list[tuple[int, Path]]:
    """``(steps, model file)`` of the run's checkpoints at multiples of ``every`` steps, and
    of its final model (at the steps its ``train_stats.json`` records)."""
    found = []
    for path in run.glob("rl_model_*_steps.zip"):
        steps = checkpoint_steps(path)
        if steps is not None and steps % every == 0:
            found.append((steps, path))
    stats = run / "train_stats.json"
    if stats.is_file():
        steps = int(json.loads(stats.read_text())["timesteps"])
        final = next(run.glob("*-v*.zip"), None)
        if final is not None and all(s != steps for s, _ in found):
            found.append((steps, final))
    return sorted(found)


def training_success(run: Path, bin_steps: int) -> list[tuple[int, float]]:
    """``(bin end, success share)`` of the Monitor's training episodes, in bins of
    ``bin_steps`` env steps (the episodes of every env, in the order they ended)."""
    episodes = []
    for path in run.glob("*.monitor.csv"):
        with open(path) as f:
            next(f)  # the Monitor's JSON header
            for row in csv.DictReader(f):
                episodes.append((float(row["t"]), int(row["l"]), row["is_success"] == "True"))
    episodes.sort()
    out, steps, done, won, edge = [], 0, 0, 0, bin_steps
    for _, length, success in episodes:
        steps += length
        done, won = done + 1, won + success
        if steps >= edge:
            out.append((edge, won / done))
            done, won, edge = 0, 0, edge + bin_steps
    return out


def wall_minutes(run: Path, model_file: Path) -> float:
    """Minutes from the run's start (the earliest ``t_start`` its Monitor files record) to
    when the model file was written (its modification time), NaN without Monitor files."""
    starts = []
    for path in run.glob("*.monitor.csv"):
        with open(path) as f:
            starts.append(json.loads(f.readline().lstrip("#"))["t_start"])
    return (model_file.stat().st_mtime - min(starts)) / 60.0 if starts else math.nan


def play(job: tuple) -> tuple[int, int, list[float]]:
    """One checkpoint on the validation episodes: ``(steps, successes, y*/W of each)``."""
    run, steps, model_file, shapes, sampled = job
    model, norm = load_checkpoint(Path(model_file))
    _, entry, _, _ = read_model_dir(run)
    kwargs = {k: v for k, v in entry["env_kwargs"].items() if not k.startswith("reward_")}
    env = gym.make(entry["env_id"], **kwargs)
    wrapper = planner_wrapper(entry)
    if wrapper is not None:
        cls, wrapper_kwargs = wrapper
        env = cls(env, **wrapper_kwargs)
    won, grips = 0, []
    for k in range(shapes):
        obs, _ = env.reset(seed=VALIDATION_SEED + k)
        if sampled:
            seed_sampling(VALIDATION_SEED + k)
        while True:
            obs, _, terminated, truncated, info = env.step(
                network_action(model, norm, obs, sampled)
            )
            if terminated or truncated:
                break
        if info["is_success"]:
            won += 1
            if math.isfinite(info["grip_force"]):  # not where torque limits admit no grip
                grips.append(info["grip_force"] / env.unwrapped.scene.object_weight)
    env.close()
    return steps, won, grips


def run_seed(run: Path) -> int | None:
    """The training seed of a run folder (its ``train_stats.json``, else the zoo's
    ``<env id>/args.yml``), or None where neither says."""
    stats = run / "train_stats.json"
    if stats.is_file():
        return json.loads(stats.read_text()).get("seed")
    for args in run.glob("*/args.yml"):
        try:
            seed = dict(yaml.load(args.read_text(), Loader=yaml.UnsafeLoader)).get("seed")
        except (yaml.YAMLError, TypeError, ValueError):
            continue
        if isinstance(seed, int):
            return seed
    return None


def run_labels(runs: list[Path]) -> list[str]:
    """Each run's label in the outputs: ``seed <n>`` where the runs' seeds differ, else the
    part of their paths that tells them apart (a log folder of each parallel run), without
    the zoo's ``ppo/<env id>_<n>`` folders."""
    seeds = [run_seed(run) for run in runs]
    if None not in seeds and len(set(seeds)) == len(seeds):
        return [f"seed {s}" for s in seeds]
    parts = [run.resolve().parts for run in runs]
    if len(runs) == 1 or len(set(parts)) < len(parts):
        return [run.resolve().name for run in runs]
    head = 0  # common leading and trailing folders are left out
    while all(len(p) > head + 1 and p[head] == parts[0][head] for p in parts):
        head += 1
    tail = 0
    while all(len(p) > head + tail + 1 and p[-1 - tail] == parts[0][-1 - tail] for p in parts):
        tail += 1
    return ["/".join(p[head : len(p) - tail]) for p in parts]


def curves(
    runs: list[Path], shapes: int, every: int, workers: int, sampled: bool = False
) -> list[dict]:
    """One row per run and checkpoint: steps, success rate, mean y*/W (NaN without one);
    ``sampled`` plays actions drawn from the policy's distribution instead of its mean."""
    labels = dict(zip(map(str, runs), run_labels(runs), strict=True))
    jobs = [
        (str(run), steps, str(path), shapes, sampled)
        for run in runs
        for steps, path in checkpoints(run, every)
    ]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            results = list(pool.map(play, jobs, chunksize=1))
    else:
        results = [play(job) for job in jobs]
    rows = []
    for (run, _, path, *_), (steps, won, grips) in zip(jobs, results, strict=True):
        rows.append(
            {
                "run": labels[run],
                "steps": steps,
                "success_rate": won / shapes,
                "grip_W_mean": float(np.mean(grips)) if grips else math.nan,
                "wall_min": wall_minutes(Path(run), Path(path)),
                "model": path,
            }
        )
    return rows


def best(rows: list[dict]) -> dict:
    """The row of the model to keep: the highest validation success, then the lowest mean
    ``y*/W`` (none counts as the highest), then the fewest steps."""

    def grip(row: dict) -> float:
        return math.inf if math.isnan(row["grip_W_mean"]) else row["grip_W_mean"]

    return min(rows, key=lambda r: (-r["success_rate"], grip(r), r["steps"]))


def plot(path: Path, rows: list[dict], training: dict[str, list], title: str) -> None:
    """Three panels: success (training episodes thin, checkpoints with the seed band) and
    y*/W at the checkpoints against env steps, and each run's checkpoints' success against
    wall time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    for name, points in training.items():
        if points:
            x, y = zip(*points, strict=True)
            axes[0].plot(x, y, lw=0.8, alpha=0.5, label=f"training episodes, {name}")
    runs = {r["run"] for r in rows}
    # the checkpoints every run has; each run's final model (at its own steps) on its own
    steps = sorted(
        s for s in {r["steps"] for r in rows} if sum(r["steps"] == s for r in rows) == len(runs)
    )
    finals = [r for r in rows if r["steps"] not in steps]
    for ax, key in zip(axes[:2], ("success_rate", "grip_W_mean"), strict=True):
        by_step = [np.array([r[key] for r in rows if r["steps"] == s], float) for s in steps]
        mean = [np.nanmean(v) if np.isfinite(v).any() else math.nan for v in by_step]
        lo = [np.nanmin(v) if np.isfinite(v).any() else math.nan for v in by_step]
        hi = [np.nanmax(v) if np.isfinite(v).any() else math.nan for v in by_step]
        ax.plot(steps, mean, "k-o", ms=3, label="checkpoints: mean over seeds")
        ax.fill_between(steps, lo, hi, color="k", alpha=0.15, label="lowest to highest seed")
        if finals:
            ax.plot(
                [r["steps"] for r in finals], [r[key] for r in finals], "kx", label="final models"
            )
        ax.set_xlabel("env steps")
        ax.ticklabel_format(axis="x", style="sci", scilimits=(6, 6))
    for name in dict.fromkeys(r["run"] for r in rows):
        mine = sorted((r["wall_min"], r["success_rate"]) for r in rows if r["run"] == name)
        axes[2].plot(*zip(*mine, strict=True), "-o", ms=3, label=name)
    axes[2].set_xlabel("wall time of the run (minutes)")
    axes[2].set_ylabel("success rate")
    axes[2].set_ylim(0, 1.02)
    axes[2].legend(fontsize=7)
    axes[0].set_ylabel("success rate")
    axes[0].set_ylim(0, 1.02)
    axes[1].set_ylabel("y* / W over successes (lower is better)")
    axes[0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m agents.learning_curves",
        description="Success and y* against env steps for PPO runs (one per seed) of one env "
        "id: the training episodes' success, and each checkpoint played deterministically (or "
        "with --sampled, sampled) on "
        "validation shapes. Writes learning_curves.png and learning_curves.csv into --out.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("runs", nargs="+", help="zoo run folders (<log folder>/ppo/<id>_<n>)")
    parser.add_argument("--shapes", type=positive_int, default=20, help="validation episodes")
    parser.add_argument("--every", type=positive_int, default=250_000, help="checkpoint spacing")
    parser.add_argument("--bin", type=positive_int, default=50_000, help="training-curve bin")
    parser.add_argument("--workers", type=workers, default=1, help="processes")
    parser.add_argument(
        "--sampled", action="store_true",
        help="play actions drawn from the policy's distribution, seeded with each validation "
        "episode's seed (default: off, the distribution's mean)",
    )  # fmt: skip
    parser.add_argument("--out", default="runs/learning_curves", help="output directory")
    parser.add_argument(
        "--best-out", metavar="DIR",
        help="also write the model directory of the best model played (the highest "
        "validation success, then the lowest y*/W, then the fewest steps) to DIR; the runs "
        "must have finished (default: none)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    runs = [Path(r) for r in args.runs]
    if len({run.resolve() for run in runs}) < len(runs):
        parser.error(f"a run folder is given twice: {args.runs}")
    for run in runs:
        if not run.is_dir():
            parser.error(f"{str(run)!r}: no such folder")
        if not any(run.glob("*/config.yml")):
            parser.error(
                f"{str(run)!r} is not a zoo run folder (<log folder>/ppo/<env id>_<n>, with "
                "<env id>/config.yml)"
            )
        if not any(run.glob("rl_model_*_steps.zip")):
            parser.error(
                f"{str(run)!r} is a run folder with no checkpoints yet: they are saved every "
                "--save-freq env steps of agents.train_ppo (default 25000; a shorter run, or "
                "one with --save-freq 0, saves none)"
            )
    env_ids = {read_model_dir(run)[1]["env_id"] for run in runs}
    if len(env_ids) != 1:
        parser.error(f"the runs trained on different env ids: {sorted(env_ids)}")
    if args.best_out:
        for run in runs:
            if not (run / "train_stats.json").is_file():
                parser.error(f"--best-out: {str(run)!r} has not finished (no train_stats.json)")
        if (Path(args.best_out) / "model.zip").exists():
            parser.error(f"--best-out {args.best_out} already holds a model.zip")
        if problem := out_dir_problem(Path(args.best_out)):
            parser.error(f"--best-out {problem}")
    if problem := out_dir_problem(Path(args.out)):
        parser.error(f"--out {problem}")
    out = Path(args.out)
    rows = curves(runs, args.shapes, args.every, args.workers, args.sampled)
    with open(out / "learning_curves.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    training = {
        label: training_success(run, args.bin)
        for run, label in zip(runs, run_labels(runs), strict=True)
    }
    play_mode = "sampled" if args.sampled else "deterministic"
    title = (
        f"{env_ids.pop()}: {len(runs)} seeds, {args.shapes} validation episodes a checkpoint, "
        f"{play_mode}"
    )
    plot(out / "learning_curves.png", rows, training, title)
    for r in rows:
        print(f"{r['run']} {r['steps']:>9,d} steps: success {r['success_rate']:.2f}, "
              f"y*/W {r['grip_W_mean']:.2f}")  # fmt: skip
    print(f"wrote {out}/learning_curves.png and learning_curves.csv")
    if args.best_out:
        chosen = best(rows)
        export_checkpoint(chosen["model"], args.best_out)
        print(f"wrote {args.best_out}: {chosen['run']} at {chosen['steps']:,d} steps")


if __name__ == "__main__":
    main()
