"""Compare the scripted planner, trained PPO agents and a random policy on fixed seeds.

    python -m agents.evaluate [--models DIR ...] [--sampled DIR ...] [--planner-in-place]
        [--rllib-checkpoint PATH ...] [--episodes N] [--out DIR] [--workers 2]
        [--results-page docs/results.md [--readme README.md]]
        [--friction 0,0.1,0.2,0.3,0.4 [--friction-page docs/friction_results.md]]
        [--uncertainty 0,0.005,0.01,0.02 [--uncertainty-page docs/uncertainty_results.md]]

Suites: ``bundled`` (every bundled scene from its start, ``--bundled-episodes`` seeds each),
``heldout`` (``--episodes`` random shapes drawn with ``reset(seed=HELDOUT_SEED + k)``, seeds
that training never uses, the hand starting where the scene puts it), ``wide``
(``--wide-episodes`` such shapes in the randomizer's wider ranges, 3-12 vertices and aspect
to 1:5), ``lift`` (``--lift-episodes`` of the held-out shapes from the planner's first
pre-liftoff placement, ``start="placement"``) and ``perturbed`` (``--perturbed-episodes``
fig13 episodes from the env's ``"random"`` start, the pre-liftoff placement perturbed). Every
policy meets the same scenes, starts and seeds. Writes
``episodes.csv`` (one row per episode), ``summary.csv``, ``summary.md`` (the table, also
printed), ``paired.csv`` (every policy against the planner on the same seeds, shape by
shape: ``agents.summary.paired_rows``), ``summary.png`` (bar charts) and ``<policy>.gif``
(one fig13 episode per policy) into ``--out``; with ``--results-page PATH`` also the
results page (``docs/results.md``: the tables with the date, the commit and the command),
which is written nowhere else, and with ``--readme PATH`` that README's results block from
it (``agents.summary.readme_results``).
``--friction`` plays every episode at each listed Coulomb coefficient (the env's
``friction``: a step friction can resist jams); the summary has a row per coefficient and
``friction.png`` plots success against it, and ``--friction-page PATH`` writes that table
and plot as a page (:mod:`agents.sweep_page`, the plot into ``images/`` beside it).
``--uncertainty`` likewise plays every episode at each listed standard deviation of the
object's vertices (the env's ``uncertainty``, palm widths: the same seeds give every policy
the same perturbations), with ``uncertainty.png`` and ``--uncertainty-page PATH``. Every row
says what its policy calls at test time (``test_time``: ``agents.models.TEST_TIMES``). A
model plays its policy's mean action; ``--sampled`` plays the models it lists also with
actions drawn from their policy's distribution (rows ``ppo_<name>_sampled``: still the network
alone, torch's generator seeded with each episode's seed so that every episode replays);
``--planner-in-place`` adds the planner lifting only from where the env puts the hand (row
``scripted_in_place``: no re-placement, no exploration). See
``docs/training.md`` for the metrics. The suites, policies and episodes: ``agents.episodes``;
the statistics, tables, chart and results page: ``agents.summary``.
"""

from __future__ import annotations

import argparse
import math
import os
import shlex
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

import grasp_env
from agents.episodes import (
    GIF_SCENE,
    HELDOUT_SEED,
    SCRIPTED_KINDS,
    SHAPE_SUITES,
    Episode,
    PolicySpec,
    default_policies,
    run_episode,
    run_job,
)
from agents.provenance import git_commit, utc_now
from agents.summary import (
    README_BEGIN,
    README_END,
    REFERENCE_NAMES,
    bar_chart,
    markdown_table,
    paired_rows,
    results_page,
    summarize,
    update_readme,
    write_csv,
    write_gif,
)
from agents.sweep_page import FRICTION, UNCERTAINTY, Sweep, sweep_page, sweep_plot
from grasp_env.cli import (
    MAX_WORKERS,
    HelpFormatter,
    existing_dir,
    file_problem,
    nonnegative_int,
    out_dir_problem,
    positive_int,
    read_text,
    workers,
)
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.envs.uncertainty import MAX_UNCERTAINTY
from grasp_env.mechanics.friction import MU_MAX


def evaluate(
    specs: list[PolicySpec],
    out: Path,
    episodes: int,
    bundled_episodes: int = 1,
    scenes: list[str] | None = None,
    max_steps: int | None = None,
    workers: int = 1,
    wide_episodes: int = 0,
    perturbed_episodes: int = 0,
    lift_episodes: int = 0,
    frictions: Sequence[float] = (0.0,),
    uncertainties: Sequence[float] = (0.0,),
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Run every policy on every suite at every friction and uncertainty level, write every
    output into ``out``; returns the summary's rows and the shape-by-shape comparison's
    (``paired.csv``, :func:`agents.summary.paired_rows`)."""
    out.mkdir(parents=True, exist_ok=True)
    scenes = scenes if scenes is not None else grasp_env.bundled_scenes()
    episodes_at = [
        (spec, "bundled", scene, seed)
        for spec in specs
        for scene in scenes
        for seed in range(bundled_episodes)
    ]
    episodes_at += [
        (spec, suite, _suite_scene(suite, HELDOUT_SEED + k), HELDOUT_SEED + k)
        for suite, n in (
            ("heldout", episodes),
            ("wide", wide_episodes),
            ("lift", lift_episodes),
            ("perturbed", perturbed_episodes),
        )
        for spec in specs
        for k in range(n)
    ]
    jobs = [
        (*e, max_steps, None, mu, sigma)
        for mu in frictions
        for sigma in uncertainties
        for e in episodes_at
    ]
    if workers > 1:
        with ProcessPoolExecutor(workers, initializer=_one_thread) as pool:
            results = _progress(pool.map(run_job, jobs, chunksize=1), len(jobs))
    else:
        _one_thread()
        results = _progress(map(run_job, jobs), len(jobs))
    write_csv(out / "episodes.csv", [asdict(e) for e in results])
    test_times = {spec.name: spec.test_time for spec in specs}
    rows = summarize(results, test_times)
    write_csv(out / "summary.csv", rows)
    paired = [row for ref in REFERENCE_NAMES for row in paired_rows(results, test_times, ref)]
    if paired:
        write_csv(out / "paired.csv", paired)
    table = markdown_table(rows)
    (out / "summary.md").write_text(table)
    bar_chart(out / "summary.png", rows)
    for sweep, levels in ((FRICTION, frictions), (UNCERTAINTY, uncertainties)):
        if len(levels) > 1:
            sweep_plot(out / f"{sweep.key}.png", rows, sweep)
    for spec in specs:
        frames: list[np.ndarray] = []
        run_episode(spec, "bundled", GIF_SCENE, 0, max_steps, frames)
        write_gif(out / f"{spec.name}.gif", frames, FrictionlessGraspEnv.metadata["render_fps"])
    return rows, paired


def _suite_scene(suite: str, seed: int) -> str:
    """The scene column of a seeded suite's episode."""
    return SHAPE_SUITES[suite]["scene"] if suite == "perturbed" else f"shape_{seed}"


def _progress(episodes, total: int) -> list[Episode]:
    """Collect the episodes, printing one line per episode to stderr."""
    out = []
    for i, e in enumerate(episodes, 1):
        status = "success" if e.success else ("error" if e.error else "no grasp")
        print(f"[{i}/{total}] {e.policy} {e.scene}: {status}", file=sys.stderr, flush=True)
        out.append(e)
    return out


def _one_thread() -> None:
    import torch

    torch.set_num_threads(1)


#: The project's docs, whose ``training.md`` a results page links to wherever it is written.
DOCS = Path(__file__).resolve().parents[1] / "docs"


def results_page_problem(path: Path) -> str | None:
    """Why the results page cannot be written at ``path``, or None: checked before any
    episode runs. Its folder must exist: the page links to the docs relative to it."""
    return file_problem(path, make_folder=False)


def readme_problem(path: Path) -> str | None:
    """Why the README's results block cannot be written at ``path``, or None: checked
    before any episode runs."""
    if not path.is_file():
        return f"{path} is not a file"
    try:
        text = read_text(path)
    except ValueError as exc:
        return str(exc)
    if not 0 <= text.find(README_BEGIN) < text.find(README_END):
        return f"{path} has no results block (the lines {README_BEGIN!r} ... {README_END!r})"
    return None


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluate",
        description="Compare the scripted planner, trained agents and a random policy on the "
        "same scenes and seeds: every bundled scene (suite 'bundled') and held-out random shapes "
        "(suite 'heldout', seeds training never uses), with the optional suites 'wide', 'lift' "
        "and 'perturbed'. Writes episodes.csv, summary.csv, summary.md (also printed), "
        "paired.csv (each policy against the planner, shape by shape), "
        "summary.png and one GIF per policy into --out, and with --results-page the results "
        "page; each row's test_time says what its policy calls at test time (network, "
        "planner or simulator); docs/training.md explains the metrics.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "--models",
        nargs="*",
        type=existing_dir,
        metavar="DIR",
        help="model directories or zoo run folders (default: agents/models/*; the option alone: "
        "no PPO model)",
    )
    parser.add_argument(
        "--sampled",
        nargs="+",
        type=existing_dir,
        default=[],
        metavar="DIR",
        help="model directories or zoo run folders to play also with actions drawn from their "
        "policy's distribution (seeded with each episode's seed), as ppo_<name>_sampled "
        "(default: none; every model plays the distribution's mean)",
    )
    parser.add_argument(
        "--rllib-checkpoint",
        nargs="+",
        action="extend",
        type=existing_dir,
        default=[],
        metavar="PATH",
        help="agents.train_rllib run directories or their checkpoint/ (needs ray[rllib]; "
        "default: none)",
    )
    parser.add_argument(
        "--episodes", type=positive_int, default=20, metavar="N", help="held-out shapes"
    )
    parser.add_argument(
        "--wide-episodes",
        type=nonnegative_int,
        default=0,
        metavar="N",
        help="held-out shapes in the randomizer's wide ranges, suite 'wide'",
    )
    parser.add_argument(
        "--lift-episodes",
        type=nonnegative_int,
        default=0,
        metavar="N",
        help="held-out shapes from the planner's pre-liftoff placement, suite 'lift'",
    )
    parser.add_argument(
        "--perturbed-episodes",
        type=nonnegative_int,
        default=0,
        metavar="N",
        help="fig13 episodes from perturbed starts (start='random'), suite 'perturbed'",
    )
    parser.add_argument(
        "--bundled-episodes", type=positive_int, default=1, metavar="N", help="seeds per scene"
    )
    parser.add_argument(
        "--scene",
        "--scenes",
        dest="scenes",
        nargs="+",
        metavar="SCENE",
        help="bundled scenes (default: all)",
    )
    parser.add_argument(
        "--max-steps",
        type=positive_int,
        metavar="N",
        help="episode length (default: the env's time limit, 200)",
    )
    parser.add_argument(
        "--workers",
        type=workers,
        default=1,
        help=f"processes, at most 4 x the CPUs = {MAX_WORKERS}",
    )
    parser.add_argument("--out", default="runs/evaluation", help="output directory")
    parser.add_argument(
        "--results-page",
        metavar="PATH",
        help="also write the results page there (docs/results.md is the shipped one; "
        "default: none, no page is written)",
    )
    parser.add_argument(
        "--readme",
        metavar="PATH",
        help="with --results-page, also rewrite the results block of that README (README.md "
        "is the shipped one) from the page: the heldout, lift and perturbed tables",
    )
    parser.add_argument(
        "--no-scripted", action="store_true", help="leave the planner out (default: off)"
    )
    parser.add_argument(
        "--planner-in-place",
        action="store_true",
        help="also the planner lifting only from where the env puts the hand, without "
        "re-placing it or exploring (row scripted_in_place; default: off)",
    )
    for sweep, parse, metavar, what in (
        (FRICTION, friction_levels, "MU,MU,...", "Coulomb coefficients"),
        (UNCERTAINTY, uncertainty_levels, "SIGMA,SIGMA,...",
         "standard deviations of the object's vertices (palm widths)"),
    ):  # fmt: skip
        parser.add_argument(
            f"--{sweep.key}", type=parse, default=(0.0,), metavar=metavar,
            help=f"{what} to play every episode at (the env's {sweep.key})",
        )  # fmt: skip
        parser.add_argument(
            f"--{sweep.key}-page", metavar="PATH",
            help=f"also write the success-against-{sweep.key} page there (with two or more "
            f"--{sweep.key} levels; docs/{sweep.key}_results.md is the shipped one)",
        )  # fmt: skip
    args = parser.parse_args(argv)
    try:
        specs = default_policies(
            args.models, args.rllib_checkpoint, args.sampled, args.planner_in_place
        )
    except ValueError as exc:
        parser.error(str(exc))
    if args.no_scripted:
        specs = [s for s in specs if s.kind not in SCRIPTED_KINDS]
    known = grasp_env.bundled_scenes()
    for scene in args.scenes or []:
        if scene not in known:
            parser.error(f"--scenes {scene!r} is not a bundled scene; choose from {known}")
    if args.readme and not args.results_page:
        parser.error("--readme needs --results-page (the block is written from that page)")
    pages = [
        (sweep, levels, Path(page))
        for sweep, levels, page in (
            (FRICTION, args.friction, args.friction_page),
            (UNCERTAINTY, args.uncertainty, args.uncertainty_page),
        )
        if page
    ]
    for sweep, levels, _ in pages:
        if len(levels) < 2:
            parser.error(f"--{sweep.key}-page needs two or more --{sweep.key} levels")
    # the arguments agree; now the files (the output folder is made here)
    if problem := out_dir_problem(Path(args.out)):
        parser.error(f"--out {problem}")
    if args.results_page and (problem := results_page_problem(Path(args.results_page))):
        parser.error(f"--results-page {problem}")
    if args.readme and (problem := readme_problem(Path(args.readme))):
        parser.error(f"--readme {problem}")
    for sweep, _, page in pages:
        if problem := results_page_problem(page):
            parser.error(f"--{sweep.key}-page {problem}")
    rows, paired = evaluate(
        specs,
        Path(args.out),
        args.episodes,
        args.bundled_episodes,
        args.scenes,
        args.max_steps,
        args.workers,
        args.wide_episodes,
        args.perturbed_episodes,
        args.lift_episodes,
        args.friction,
        args.uncertainty,
    )
    print(markdown_table(rows), end="")
    print(f"wrote {args.out}/: episodes.csv summary.csv summary.md paired.csv summary.png *.gif")
    command = shlex.join(["python", "-m", "agents.evaluate", *argv])
    if args.results_page:
        target = Path(args.results_page)
        training = os.path.relpath(DOCS / "training.md", target.resolve().parent)
        page = results_page(
            rows, command, utc_now(), git_commit(), Path(training).as_posix(), paired
        )
        target.write_text(page)
        print(f"wrote {args.results_page}")
    if args.readme:
        readme, page = Path(args.readme), Path(args.results_page)
        update_readme(readme, page, os.path.relpath(page, readme.resolve().parent))
        print(f"wrote the results block of {args.readme}")
    for sweep, _, page in pages:
        write_sweep_page(page, rows, sweep, command)


def write_sweep_page(path: Path, rows: list[dict[str, Any]], sweep: Sweep, command: str) -> None:
    """The sweep's page at ``path``, its plot in ``images/`` beside it."""
    image = Path("images") / f"{path.stem}.png"
    (path.parent / "images").mkdir(exist_ok=True)
    sweep_plot(path.parent / image, rows, sweep)
    path.write_text(sweep_page(rows, sweep, image.as_posix(), command, utc_now(), git_commit()))
    print(f"wrote {path} and {path.parent / image}")


def levels(text: str, most: float) -> tuple[float, ...]:
    """Comma-separated levels, each in [0, ``most``], distinct, in increasing order."""
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"not comma-separated numbers: {text!r}") from None
    for x in values:
        if not (math.isfinite(x) and 0.0 <= x <= most):
            raise argparse.ArgumentTypeError(f"each must be in [0, {most:g}], got {x!r}")
    if len(set(values)) != len(values):
        raise argparse.ArgumentTypeError(f"levels repeat: {text!r}")
    return tuple(sorted(values))


def friction_levels(text: str) -> tuple[float, ...]:
    """``--friction``'s Coulomb coefficients, each in [0, MU_MAX]."""
    return levels(text, MU_MAX)


def uncertainty_levels(text: str) -> tuple[float, ...]:
    """``--uncertainty``'s standard deviations of the vertices, each in [0, MAX_UNCERTAINTY]
    palm widths."""
    return levels(text, MAX_UNCERTAINTY)


if __name__ == "__main__":
    main()
