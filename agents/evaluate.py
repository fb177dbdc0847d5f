"""Compare the scripted planner, trained PPO agents and a random policy on fixed seeds.

    python -m agents.evaluate [--models DIR ...] [--rllib-checkpoint PATH ...] [--episodes N]
        [--out DIR] [--workers 2] [--results-page docs/results.md]

Suites: ``bundled`` (every bundled scene from its start, ``--bundled-episodes`` seeds each),
``heldout`` (``--episodes`` random shapes drawn with ``reset(seed=HELDOUT_SEED + k)``, seeds
that training never uses, the hand starting where the scene puts it), ``wide``
(``--wide-episodes`` such shapes in the randomizer's wider ranges, 3-12 vertices and aspect
to 1:5), ``lift`` (``--lift-episodes`` of the held-out shapes from the planner's first
pre-liftoff placement, ``start="placement"``) and ``perturbed`` (``--perturbed-episodes``
fig13 episodes from the env's ``"random"`` start, the pre-liftoff placement perturbed). Every
policy meets the same scenes, starts and seeds. Writes
``episodes.csv`` (one row per episode), ``summary.csv``, ``summary.md`` (the table, also
printed), ``summary.png`` (bar charts) and ``<policy>.gif`` (one fig13 episode per policy)
into ``--out``; with ``--results-page PATH`` also the results page (``docs/results.md``: the
tables with the date, the commit and the command), which is written nowhere else. Every row
says what its policy calls at test time (``test_time``: ``agents.models.TEST_TIMES``). See
``docs/training.md`` for the metrics.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import functools
import itertools
import math
import os
import shlex
import subprocess
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np

import grasp_env
from agents.models import MODEL_DIR, TEST_TIMES, load_agent
from grasp_env.cli import HelpFormatter, nonnegative_int, out_dir_problem, positive_int
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.envs.shapes import WIDE_SHAPE_RANGES

#: First seed of the held-out shapes. Training seeds its envs with ``seed + rank`` and its
#: evaluation env with ``seed + 1000`` (small seeds); these streams never meet them.
HELDOUT_SEED = 1_000_000
#: Env kwargs of the held-out suite: fig13's hand, a new random shape per seed, the hand
#: starting where the scene puts it (the "from anywhere" task).
HELDOUT_KWARGS = {"scene": "fig13", "shape_randomizer": True, "start": "scene"}
#: Env kwargs of the wide held-out suite: the same with the randomizer's wider ranges
#: (``grasp_env.envs.shapes.WIDE_SHAPE_RANGES``: 3-12 vertices, aspect to 1:5).
WIDE_KWARGS = {"scene": "fig13", "shape_randomizer": dict(WIDE_SHAPE_RANGES), "start": "scene"}
#: Env kwargs of the lifting suite: the held-out shapes, the hand starting at the planner's
#: first pre-liftoff placement for each (``start="placement"``, the task of
#: ``FrictionlessGraspLift-v0``).
LIFT_KWARGS = {"scene": "fig13", "shape_randomizer": True, "start": "placement"}
#: Env kwargs of the perturbed-start suite: fig13 from the ``"random"`` start (the pre-liftoff
#: placement perturbed in palm pose and finger angles), one draw per seed.
PERTURBED_KWARGS = {"scene": "fig13", "start": "random"}
#: Env kwargs of the seeded suites, by suite name (every policy meets the same draws).
SHAPE_SUITES = {
    "heldout": HELDOUT_KWARGS,
    "wide": WIDE_KWARGS,
    "lift": LIFT_KWARGS,
    "perturbed": PERTURBED_KWARGS,
}
#: Env set-up of the scripted planner (``agents.scripted.ScriptedPolicy``, which plans from
#: the env's state at every reset with exact knowledge of the scene, as the paper assumes):
#: the scene's start with palm actions, so that where lifting with the palm fixed fails (as
#: in the paper's set-up) it can drive the hand to the whole planner's placement, tilted palm
#: included. On fig13 it never moves the palm.
SCRIPTED_KWARGS = {"palm_control": True, "start": "scene"}
#: Env set-up of the random policy: the paper's (palm fixed where the scene puts it).
RANDOM_KWARGS = {"palm_control": False, "start": "scene"}
#: Env kwargs that a suite sets and a policy's own set-up must not override.
SUITE_KEYS = ("scene", "shape_randomizer", "start", "time_limit", "shape_pool")
GIF_SCENE, GIF_SIZE, GIF_EVERY = "fig13", (320, 240), 2
BOOTSTRAP_SAMPLES = 2000
#: What each kind of policy calls at test time (``agents.models.TEST_TIMES``); a ``"ppo"``
#: model's is its training entry's (``agents.models.entry_test_time``). An RLlib checkpoint
#: plays on its env id alone.
KIND_TEST_TIMES = {"scripted": "planner", "random": "network", "rllib": "network"}
#: The suites as the summary lists them (``fig13`` is the ``bundled`` suite's fig13
#: episodes), with what each one is, for the results page.
SUITE_TITLES = {
    GIF_SCENE: "fig13, the paper's scene from its start",
    "bundled": "every bundled scene from its start",
    "heldout": "held-out random shapes, the hand where the scene puts it",
    "wide": "held-out random shapes in the wide ranges, the hand where the scene puts it",
    "lift": "held-out random shapes, the hand at the planner's pre-liftoff placement",
    "perturbed": "fig13 from perturbed starts",
}


# ---------------------------------------------------------------------- policies
@dataclass(frozen=True)
class PolicySpec:
    """A policy to evaluate: ``kind`` is "scripted", "random", "ppo" (with ``model_dir``) or
    "rllib" (``model_dir`` is an RLlib checkpoint, see ``agents.rllib_policy``); ``wrapper``:
    the wrapper class and arguments of a model that plays beside the planner
    (``agents.planner_agents.planner_wrapper``); ``test_time``: what the policy calls at test
    time (``agents.models.TEST_TIMES``; by default its kind's, ``KIND_TEST_TIMES``, and for
    a "ppo" model its wrapper's declaration, ``PlannerAgent.test_time_of``, or ``"network"``
    without one: as ``agents.models.entry_test_time`` reads its entry)."""

    name: str
    kind: str
    env_kwargs: dict = field(default_factory=dict)
    model_dir: str | None = None
    wrapper: tuple[type[gym.Wrapper], dict] | None = None
    test_time: str = ""

    def __post_init__(self) -> None:
        if not self.test_time:
            if self.kind == "ppo":  # the network, and what the wrapper it plays through calls
                cls, kwargs = self.wrapper or (None, {})
                test_time = "network" if cls is None else cls.test_time_of(kwargs)
            elif self.kind in KIND_TEST_TIMES:
                test_time = KIND_TEST_TIMES[self.kind]
            else:
                raise ValueError(f"policy {self.name!r}: a {self.kind!r} policy needs test_time")
            object.__setattr__(self, "test_time", test_time)
        if self.test_time not in TEST_TIMES:
            raise ValueError(f"policy {self.name!r}: test_time must be one of {TEST_TIMES}")


def ppo_spec(model_dir: str | os.PathLike) -> PolicySpec:
    """The spec of a trained model directory: its training env set-up (palm control, start,
    the wrapper that plays it beside the planner) from its saved config, with the env's
    default reward weights like every other policy."""
    from agents.planner_agents import planner_wrapper

    _, _, name, entry = load_agent(model_dir)
    kwargs = {
        k: v
        for k, v in entry.get("env_kwargs", {}).items()
        if k not in SUITE_KEYS and not k.startswith("reward_")  # one return for all policies
    }
    return PolicySpec(f"ppo_{name}", "ppo", kwargs, str(model_dir), planner_wrapper(entry))


def rllib_spec(path: str | os.PathLike) -> PolicySpec:
    """The spec of an ``agents.train_rllib`` run directory or checkpoint: the set-up of the
    env id it trained on (the id's registered kwargs and the config's, from the config saved
    beside the checkpoint), less the suite's keys and reward weights as in :func:`ppo_spec`."""
    from agents.rllib_policy import load_run

    checkpoint, env_id, entry = load_run(path)
    set_up = {**gym.spec(env_id).kwargs, **(entry.get("env_kwargs") or {})}
    kwargs = {
        k: v for k, v in set_up.items() if k not in SUITE_KEYS and not k.startswith("reward_")
    }
    return PolicySpec(f"rllib_{env_id}", "rllib", kwargs, str(checkpoint))


def make_policy(spec: PolicySpec, env: gym.Env) -> tuple[Callable, Callable]:
    """``(reset(obs, info, seed), act(obs))`` for a spec on an env."""
    if spec.kind == "scripted":
        from agents.scripted import ScriptedPolicy

        policy = ScriptedPolicy(env)
        return (lambda obs, info, seed: policy.reset(obs, info)), policy.act
    if spec.kind == "random":
        box = env.action_space
        state = {}

        def reset(obs, info, seed):
            state["rng"] = np.random.default_rng(seed)

        def act(obs):
            return state["rng"].uniform(box.low, box.high).astype(np.float32)

        return reset, act
    if spec.kind == "rllib":
        return (lambda obs, info, seed: None), _load_rllib(spec.model_dir).act
    model, norm, _, _ = _load_agent(spec.model_dir)

    def act(obs):
        x = norm.normalize_obs(obs) if norm is not None else obs
        return model.predict(x, deterministic=True)[0]

    return (lambda obs, info, seed: None), act


_load_agent = functools.cache(load_agent)  # once per model and process


@functools.cache
def _load_rllib(checkpoint: str):
    from agents.rllib_policy import RLlibPolicy

    return RLlibPolicy(checkpoint)


# ---------------------------------------------------------------------- episodes
@dataclass
class Episode:
    """One evaluated episode; ``grip`` is y* and ``grip_W`` is y* / object weight."""

    suite: str
    scene: str
    policy: str
    seed: int
    steps: int = 0
    ret: float = 0.0
    success: bool = False
    reached: bool = False
    steps_to_closure: float = math.nan
    grip: float = math.nan
    grip_W: float = math.nan
    dropped: bool = False
    jammed: bool = False
    error: str = ""


def make_env(spec: PolicySpec, suite_kwargs: dict, max_steps: int | None, **extra) -> gym.Env:
    kwargs = {**spec.env_kwargs, **suite_kwargs, **extra}
    if max_steps is not None:
        kwargs["time_limit"] = max_steps
    env = gym.make("FrictionlessGrasp-v0", **kwargs)
    if spec.wrapper is None:
        return env
    cls, wrapper_kwargs = spec.wrapper
    return cls(env, **wrapper_kwargs)


def run_episode(
    spec: PolicySpec, suite: str, scene: str, seed: int, max_steps: int | None, frames=None
) -> Episode:
    """Run one episode to its end; appends rendered frames to ``frames`` if given."""
    suite_kwargs = SHAPE_SUITES.get(suite, {"scene": scene})
    extra = {}
    if frames is not None:
        extra = {"render_mode": "rgb_array", "render_width": GIF_SIZE[0]}
        extra["render_height"] = GIF_SIZE[1]
    env = make_env(spec, suite_kwargs, max_steps, **extra)
    ep = Episode(suite, scene, spec.name, seed)
    try:
        reset, act = make_policy(spec, env)
        obs, info = env.reset(seed=seed)
        reset(obs, info, seed)
        while True:
            if frames is not None and ep.steps % GIF_EVERY == 0:
                frames.append(env.render())
            obs, reward, terminated, truncated, info = env.step(act(obs))
            ep.steps += 1
            ep.ret += float(reward)
            if info["is_success"] and not ep.reached:
                ep.reached, ep.steps_to_closure = True, ep.steps
            ep.dropped |= info["dropped"]
            ep.jammed |= info["jammed"] and not info["form_closure"]
            if "sim_error" in info:
                ep.error = info["sim_error"]
            if terminated or truncated:
                break
    except Exception as exc:  # a failing policy fails its episode, not the evaluation
        ep.error = f"{type(exc).__name__}: {exc}"
        print(f"{spec.name} on {scene} (seed {seed}): {ep.error}")
        env.close()
        return ep
    if frames is not None:
        frames.append(env.render())
    ep.success = bool(info["is_success"])
    if ep.success:
        ep.grip = float(info["grip_force"])
        ep.grip_W = ep.grip / env.unwrapped.scene.object_weight
    env.close()
    return ep


def _run_job(job: tuple) -> Episode:
    return run_episode(*job)


# ---------------------------------------------------------------------- statistics
def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score 95% interval of a success rate ``k / n``."""
    if n == 0:
        return math.nan, math.nan
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def bootstrap_mean(values: list[float], seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap 95% interval of the mean (nan, nan for no values)."""
    x = np.asarray(values, dtype=float)
    if len(x) == 0:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = rng.choice(x, (BOOTSTRAP_SAMPLES, len(x))).mean(axis=1)
    return float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def summarize(
    episodes: list[Episode], test_times: dict[str, str] | None = None
) -> list[dict[str, Any]]:
    """One row per (suite, policy): rates with Wilson CIs, means with bootstrap CIs, and
    ``test_time``, what the policy calls at test time (``test_times``, by policy name; "" for
    a policy it does not name).

    Suites: the paper's scene alone (``fig13``), all bundled scenes (left out where fig13 is
    the only one: its rows would repeat fig13's), the held-out shapes in the default and the
    wide ranges and from the planner's placement, fig13 from perturbed starts.
    """
    rows = []
    test_times = test_times or {}
    bundled = [e for e in episodes if e.suite == "bundled"]
    groups = {
        GIF_SCENE: [e for e in bundled if e.scene == GIF_SCENE],
        "bundled": bundled if any(e.scene != GIF_SCENE for e in bundled) else [],
        "heldout": [e for e in episodes if e.suite == "heldout"],
        "wide": [e for e in episodes if e.suite == "wide"],
        "lift": [e for e in episodes if e.suite == "lift"],
        "perturbed": [e for e in episodes if e.suite == "perturbed"],
    }
    policies = list(dict.fromkeys(e.policy for e in episodes))
    for (suite, group), policy in itertools.product(groups.items(), policies):
        eps = [e for e in group if e.policy == policy]
        if not eps:
            continue
        n, k = len(eps), sum(e.success for e in eps)
        # a grasp whose torque limits admit no grip has y* = inf: counted, not averaged
        grips = [e.grip_W for e in eps if e.success and math.isfinite(e.grip_W)]
        closure = [e.steps_to_closure for e in eps if e.reached]
        lo, hi = wilson(k, n)
        g_lo, g_hi = bootstrap_mean(grips)
        s_lo, s_hi = bootstrap_mean(closure)
        rows.append(
            {
                "suite": suite,
                "policy": policy,
                "test_time": test_times.get(policy, ""),
                "episodes": n,
                "success_rate": k / n,
                "success_ci_low": lo,
                "success_ci_high": hi,
                "grip_W_mean": float(np.mean(grips)) if grips else math.nan,
                "grip_W_std": float(np.std(grips)) if grips else math.nan,
                "grip_W_ci_low": g_lo,
                "grip_W_ci_high": g_hi,
                "steps_to_closure_mean": float(np.mean(closure)) if closure else math.nan,
                "steps_to_closure_ci_low": s_lo,
                "steps_to_closure_ci_high": s_hi,
                "grip_infinite": sum(e.success and math.isinf(e.grip_W) for e in eps),
                "drops": sum(e.dropped for e in eps),
                "jams": sum(e.jammed for e in eps),
                "errors": sum(bool(e.error) for e in eps),
                "mean_return": float(np.mean([e.ret for e in eps])),
            }
        )
    return rows


#: A summary cell with nothing to show (no success to average, no episode that reached closure).
EMPTY = "n/a"
#: The summary table's columns: header and alignment row.
TABLE_HEAD = (
    "| suite | policy | test time | n | success (95% CI) | y*/W mean ± sd (95% CI) "
    "| steps to closure (95% CI) | drops | jams | errors |\n"
    "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n"
)


def markdown_table(rows: list[dict[str, Any]]) -> str:
    """The summary as a markdown table (``n/a`` where a mean has no values)."""

    def num(x: float, fmt: str = ".2f") -> str:
        return format(x, fmt)

    lines = [TABLE_HEAD.rstrip("\n")]
    for r in rows:
        success = (
            f"{num(r['success_rate'])} ({num(r['success_ci_low'])}-{num(r['success_ci_high'])})"
        )
        grip = EMPTY
        if not math.isnan(r["grip_W_mean"]):
            grip = (
                f"{num(r['grip_W_mean'])} ± {num(r['grip_W_std'])} "
                f"({num(r['grip_W_ci_low'])}-{num(r['grip_W_ci_high'])})"
            )
        closure = EMPTY
        if not math.isnan(r["steps_to_closure_mean"]):
            closure = (
                f"{num(r['steps_to_closure_mean'], '.1f')} "
                f"({num(r['steps_to_closure_ci_low'], '.1f')}-"
                f"{num(r['steps_to_closure_ci_high'], '.1f')})"
            )
        lines.append(
            f"| {r['suite']} | {r['policy']} | {r['test_time']} | {r['episodes']} | {success} "
            f"| {grip} | {closure} | {r['drops']} | {r['jams']} | {r['errors']} |"
        )
    return "\n".join(lines) + "\n"


def results_page(rows: list[dict[str, Any]], command: str, date: str, commit: str) -> str:
    """The results page (``docs/results.md``): one table per suite, the date, the commit and
    the command that produced it, and which rows are network-only."""
    network = list(dict.fromkeys(r["policy"] for r in rows if r["test_time"] == "network"))
    others = {
        level: list(dict.fromkeys(r["policy"] for r in rows if r["test_time"] == level))
        for level in TEST_TIMES[1:]
    }
    lines = [
        "# Results",
        "",
        "<!-- Generated by agents.evaluate --results-page: run the command below again rather "
        "than editing this page. -->",
        "",
        f"Generated on {date} at commit `{commit}` by:",
        "",
        "```bash",
        command,
        "```",
        "",
        "Every policy meets the same scenes, starts and seeds; success is form closure off the "
        "support at the episode's last step, with its Wilson 95% interval; y\\*/W (the grip "
        "objective in object weights) is over the successes, with a bootstrap 95% interval of "
        "the mean; `n/a` where there is nothing to average. The metrics, suites and policies: "
        "[training.md](training.md#evaluation).",
        "",
        "**Test time** says what a policy calls when it plays: `network`, its network alone "
        "on the env's observation (`random`: nothing); `planner`, the scripted planner, which "
        "plans on the exact model of the scene (its fallback searches included); `simulator`, "
        "also the exact simulator on copies of the env's state beyond the env's own step. "
        "What a suite's env does for every policy alike (the `lift` suite's start at the "
        "planner's placement) is not counted.",
        "",
        f"Network-only rows: {_names(network)}.",
    ]
    for level, names in others.items():
        if names:
            lines.append(f"Rows of `{level}` policies: {_names(names)}.")
    for suite in dict.fromkeys(r["suite"] for r in rows):
        table = markdown_table([r for r in rows if r["suite"] == suite])
        lines += ["", f"## `{suite}`: {SUITE_TITLES.get(suite, suite)}", "", table.rstrip("\n")]
    return "\n".join(lines) + "\n"


def _names(names: list[str]) -> str:
    return ", ".join(f"`{n}`" for n in names) if names else "none"


#: The folders whose uncommitted changes the results page notes.
CODE_DIRS = ("grasp_env", "agents", "configs")


def git_commit(repo: Path = MODEL_DIR.parent.parent) -> str:
    """The checked-out commit (short hash), noting uncommitted changes to the code that
    decides the numbers (``grasp_env/``, ``agents/``, ``configs/``); ``unknown`` outside git."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=repo, capture_output=True, text=True
        )
        changed = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", *CODE_DIRS],
            cwd=repo,
            capture_output=True,
            text=True,
        )
    except OSError:
        return "unknown"
    if commit.returncode != 0:
        return "unknown"
    dirty = changed.returncode == 0 and changed.stdout.strip()
    return commit.stdout.strip() + (" with uncommitted changes" if dirty else "")


# ---------------------------------------------------------------------- outputs
def write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def bar_chart(path: Path, rows: list[dict[str, Any]]) -> None:
    """Success rate and mean y*/W per suite and policy, with their 95% CIs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    suites = list(dict.fromkeys(r["suite"] for r in rows))
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    width = 0.8 / len(policies)
    x = np.arange(len(suites))
    panels = (("success_rate", "success", "success rate"), ("grip_W_mean", "grip_W", "y* / W"))
    for ax, (key, ci, label) in zip(axes, panels, strict=True):
        for i, policy in enumerate(policies):
            by_suite = {r["suite"]: r for r in rows if r["policy"] == policy}
            mean = np.array([by_suite.get(s, {}).get(key, math.nan) for s in suites], float)
            lo = np.array([by_suite.get(s, {}).get(f"{ci}_ci_low", math.nan) for s in suites])
            hi = np.array([by_suite.get(s, {}).get(f"{ci}_ci_high", math.nan) for s in suites])
            err = np.nan_to_num(np.stack([mean - lo, hi - mean]).astype(float))
            ax.bar(x + i * width, np.nan_to_num(mean), width, yerr=err, capsize=3, label=policy)
        ax.set_xticks(x + width * (len(policies) - 1) / 2, suites)
        ax.set_ylabel(label)
    axes[0].set_ylim(0, 1.05)
    axes[1].set_title("over successes (lower is better)")
    # below both panels, where it covers no bar
    handles, labels = axes[0].get_legend_handles_labels()
    ncol = min(len(policies), 4)
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    rows_of_legend = math.ceil(len(policies) / ncol)
    fig.tight_layout(rect=(0, 0.06 * rows_of_legend + 0.02, 1, 1))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_gif(path: Path, frames: list[np.ndarray], fps: int) -> None:
    import imageio.v2 as imageio

    imageio.mimsave(path, frames, duration=1000 * GIF_EVERY / fps, loop=0)


# ---------------------------------------------------------------------- main
def default_policies(
    model_dirs: list[str] | None, rllib_checkpoints: Sequence[str] = ()
) -> list[PolicySpec]:
    """Scripted (when ``agents.scripted`` exists), the models, the RLlib checkpoints, random."""
    if model_dirs is None:
        model_dirs = [str(p.parent) for p in sorted(MODEL_DIR.glob("*/model.zip"))]
    specs = []
    try:
        import agents.scripted  # noqa: F401
    except ImportError:
        print("agents.scripted is not available: the scripted policy is left out")
    else:
        specs.append(PolicySpec("scripted", "scripted", SCRIPTED_KWARGS))
    specs += [ppo_spec(d) for d in model_dirs]
    specs += [rllib_spec(c) for c in rllib_checkpoints]
    specs.append(PolicySpec("random", "random", RANDOM_KWARGS))
    return specs


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
) -> list[dict[str, Any]]:
    """Run every policy on every suite, write every output into ``out``; returns the rows."""
    out.mkdir(parents=True, exist_ok=True)
    scenes = scenes if scenes is not None else grasp_env.bundled_scenes()
    jobs = [
        (spec, "bundled", scene, seed, max_steps)
        for spec in specs
        for scene in scenes
        for seed in range(bundled_episodes)
    ]
    jobs += [
        (spec, suite, _suite_scene(suite, HELDOUT_SEED + k), HELDOUT_SEED + k, max_steps)
        for suite, n in (
            ("heldout", episodes),
            ("wide", wide_episodes),
            ("lift", lift_episodes),
            ("perturbed", perturbed_episodes),
        )
        for spec in specs
        for k in range(n)
    ]
    if workers > 1:
        with ProcessPoolExecutor(workers, initializer=_one_thread) as pool:
            results = _progress(pool.map(_run_job, jobs, chunksize=1), len(jobs))
    else:
        _one_thread()
        results = _progress(map(_run_job, jobs), len(jobs))
    write_csv(out / "episodes.csv", [asdict(e) for e in results])
    rows = summarize(results, {spec.name: spec.test_time for spec in specs})
    write_csv(out / "summary.csv", rows)
    table = markdown_table(rows)
    (out / "summary.md").write_text(table)
    bar_chart(out / "summary.png", rows)
    for spec in specs:
        frames: list[np.ndarray] = []
        run_episode(spec, "bundled", GIF_SCENE, 0, max_steps, frames)
        write_gif(out / f"{spec.name}.gif", frames, FrictionlessGraspEnv.metadata["render_fps"])
    return rows


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


#: Most ``--workers`` accepted: 4 processes per CPU. More only queue for the CPUs, each one
#: holding an env, a torch runtime and the agents in memory.
MAX_WORKERS = 4 * (os.cpu_count() or 1)


class _HelpFormatter(HelpFormatter):
    """``--help`` with every option's default, zero counts included (the shared formatter
    leaves out defaults that compare equal to False)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if type(action.default) is int and "%(default)" not in (action.help or ""):
            return f"{action.help} (default: %(default)s)"
        return super()._get_help_string(action)


def results_page_problem(path: Path) -> str | None:
    """Why the results page cannot be written at ``path``, or None: checked before any
    episode runs."""
    if path.is_dir():
        return f"{path} is a directory"
    if not path.parent.is_dir():
        return f"{path}: its folder {path.parent} does not exist"
    return None


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(
        prog="python -m agents.evaluate",
        description="Compare the scripted planner, trained agents and a random policy on the "
        "same scenes and seeds: every bundled scene (suite 'bundled') and held-out random shapes "
        "(suite 'heldout', seeds training never uses), with the optional suites 'wide', 'lift' "
        "and 'perturbed'. Writes episodes.csv, summary.csv, summary.md (also printed), "
        "summary.png and one GIF per policy into --out, and with --results-page the results "
        "page; each row's test_time says what its policy calls at test time (network, "
        "planner or simulator); docs/training.md explains the metrics.",
        formatter_class=_HelpFormatter,
    )
    parser.add_argument(
        "--models",
        nargs="*",
        metavar="DIR",
        help="model directories or zoo run folders (default: agents/models/*; the option alone: "
        "no PPO model)",
    )
    parser.add_argument(
        "--rllib-checkpoint",
        nargs="+",
        action="extend",
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
        type=positive_int,
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
        "--no-scripted", action="store_true", help="leave the planner out (default: off)"
    )
    args = parser.parse_args(argv)
    if args.workers > MAX_WORKERS:
        parser.error(f"--workers must be at most 4 x the CPUs = {MAX_WORKERS}, got {args.workers}")
    try:
        specs = default_policies(args.models, args.rllib_checkpoint)
    except ValueError as exc:
        parser.error(str(exc))
    if args.no_scripted:
        specs = [s for s in specs if s.kind != "scripted"]
    known = grasp_env.bundled_scenes()
    for scene in args.scenes or []:
        if scene not in known:
            parser.error(f"--scenes {scene!r} is not a bundled scene; choose from {known}")
    if problem := out_dir_problem(Path(args.out)):
        parser.error(f"--out {problem}")
    if args.results_page and (problem := results_page_problem(Path(args.results_page))):
        parser.error(f"--results-page {problem}")
    rows = evaluate(
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
    )
    print(markdown_table(rows), end="")
    print(f"wrote {args.out}/: episodes.csv summary.csv summary.md summary.png *.gif")
    if args.results_page:
        command = shlex.join(["python", "-m", "agents.evaluate", *argv])
        date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        page = results_page(rows, command, date, git_commit())
        Path(args.results_page).write_text(page)
        print(f"wrote {args.results_page}")


if __name__ == "__main__":
    main()
