"""The scripted policy's episode rate against an earlier commit's, in the same run.

The earlier commit's ``grasp_env``, ``agents`` and ``configs`` are exported (``git archive``) to
a temporary folder. Each round runs, each in a fresh process and in rotated order: the scripted
policy (``agents.scripted.ScriptedPolicy``, planning at every reset included) of the earlier
commit and of the work tree on ``FrictionlessGrasp-v0`` with ``start="preliftoff"`` (the
default fig13 scene), playing whole episodes from the same seeds for a time budget after one
untimed episode; and LunarLander-v3 with random actions for the same budget, so that each
commit's rate can also be read against a baseline measured beside it. Reports the median over
rounds of episodes/s and steps/s and of the per-round ratios.

Usage: ``python -m benchmarks.scripted_speedup --base REV [--budget S] [--rounds N] [--out
FILE]`` from the repository root (default ``--base dff3a09``, the simulator before its
compiled core; 3 rounds of 20 s: about 3 minutes).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

from benchmarks.common import OUT, REPO, headless, parser, table, write
from grasp_env.cli import positive_float, positive_int

#: The commit measured against by default: the simulator and env before the compiled core.
BASE = "dff3a09"

#: Seeds of the episodes each side plays, in order: ``SEED + k``.
SEED = 1000

_WORKER = """
import json, sys, time
import gymnasium as gym
budget, which, seed = float(sys.argv[1]), sys.argv[2], int(sys.argv[3])
clock = time.perf_counter
if which == "lunar":
    import numpy as np
    try:
        env = gym.make("LunarLander-v3")
    except gym.error.DependencyNotInstalled:  # not gymnasium[box2d]: it breaks pygame
        print(json.dumps({"absent": 'Box2D is not installed (pip install box2d)'}))
        sys.exit(0)
    except Exception as exc:
        print(json.dumps({"absent": f"{type(exc).__name__}: {exc}"}))
        sys.exit(0)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    steps = episodes = 0
    t0 = clock()
    while clock() - t0 < budget:
        for a in rng.integers(0, 4, 1000):
            steps += 1
            if any(env.step(int(a))[2:4]):
                env.reset()
                episodes += 1
    wall = clock() - t0
else:
    import grasp_env
    from agents.scripted import ScriptedPolicy
    env = gym.make("FrictionlessGrasp-v0", start="preliftoff")
    policy = ScriptedPolicy(env)

    def episode(seed):
        obs, info = env.reset(seed=seed)
        policy.reset(obs, info)
        n, done = 0, False
        while not done:
            obs, _, terminated, truncated, _ = env.step(policy.act(obs))
            n, done = n + 1, terminated or truncated
        return n

    episode(seed - 1)  # untimed: loads compiled code from its cache
    steps = episodes = 0
    t0 = clock()
    while clock() - t0 < budget:
        steps += episode(seed + episodes)
        episodes += 1
    wall = clock() - t0
print(json.dumps({"steps": steps, "episodes": episodes, "seconds": wall}))
"""


def revision(text: str) -> str:
    """An ``argparse`` type: a commit of this repository (``git rev-parse --verify``), checked
    before any measurement."""
    try:
        found = subprocess.run(
            ["git", "rev-parse", "--verify", "--quiet", "--end-of-options", f"{text}^{{commit}}"],
            cwd=REPO, capture_output=True, text=True,
        )  # fmt: skip
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"cannot run git ({exc.strerror or exc})") from None
    if found.returncode != 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a commit of {REPO}")
    return text


def export(rev: str, into: Path) -> Path:
    """``grasp_env``, ``agents`` and ``configs`` at ``rev``, extracted under ``into``."""
    out = subprocess.run(
        ["git", "archive", rev, "grasp_env", "agents", "configs"],
        cwd=REPO, capture_output=True, check=True,
    )  # fmt: skip
    with tarfile.open(fileobj=BytesIO(out.stdout)) as tar:
        tar.extractall(into, filter="data")
    return into


def _run(tree: Path, which: str, budget: float) -> dict:
    """One worker process importing from ``tree``: its counts."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run(
        [sys.executable, "-c", _WORKER, str(budget), which, str(SEED)],
        cwd=tree, env=env, capture_output=True, text=True, timeout=budget * 20 + 600,
    )  # fmt: skip
    if out.returncode != 0:
        raise RuntimeError(f"{which} at {tree}: {out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def measure(base: Path, head: Path, budget: float, rounds: int) -> dict[str, list[dict]]:
    """Rounds of the three workers in rotated order: their counts per round."""
    jobs = [("base", base, "scripted"), ("head", head, "scripted"), ("lunar", head, "lunar")]
    runs: dict[str, list[dict]] = {name: [] for name, _, _ in jobs}
    for r in range(rounds):
        for name, tree, which in jobs[r % 3 :] + jobs[: r % 3]:
            runs[name].append(_run(tree, which, budget))
            print(f"round {r + 1}: {name} {runs[name][-1]}", flush=True)
    return runs


def report(runs: dict[str, list[dict]], base_rev: str, budget: float) -> list[str]:
    """The page's body: per side episodes/s and steps/s, and the ratios."""

    def rate(run: dict, what: str) -> float:
        return run[what] / run["seconds"]

    def median(values) -> float:
        return statistics.median(list(values))

    lunar = [r for r in runs["lunar"] if "absent" not in r]

    def to_lunar(name: str) -> str:
        if not lunar:
            return "-"
        pairs = zip(runs[name], runs["lunar"], strict=True)
        return f"{median(rate(r, 'steps') / rate(lr, 'steps') for r, lr in pairs):.4f}"

    rows = [
        [
            label,
            f"{median(rate(r, 'episodes') for r in runs[name]):.2f}",
            f"{median(rate(r, 'steps') for r in runs[name]):,.0f}",
            sum(r["episodes"] for r in runs[name]),
            to_lunar(name),
        ]
        for name, label in (("base", f"scripted policy at {base_rev}"), ("head", "scripted policy"))
    ]
    if lunar:
        rows.append(
            [
                "LunarLander-v3 (random actions)",
                f"{median(rate(r, 'episodes') for r in lunar):.1f}",
                f"{median(rate(r, 'steps') for r in lunar):,.0f}",
                sum(r["episodes"] for r in lunar),
                "1.0000",
            ]
        )
    else:
        rows.append(["LunarLander-v3", "absent", runs["lunar"][0]["absent"], "", ""])
    speedup = median(
        rate(h, "episodes") / rate(b, "episodes")
        for h, b in zip(runs["head"], runs["base"], strict=True)
    )
    return [
        f"{len(runs['base'])} rounds of {budget:g} s per side, each side in a fresh process, "
        f'rotated order; `FrictionlessGrasp-v0` with `start="preliftoff"` (fig13), whole '
        f"episodes from seeds {SEED}, {SEED + 1}, ... (one untimed episode first); medians over "
        "rounds.",
        "",
        *table(
            ["side", "episodes/s", "steps/s", "episodes", "steps/s ratio to LunarLander-v3"],
            rows,
        ),
        "",
        f"* target: scripted policy episode rate >= 10x the earlier commit's: **{speedup:.1f}x** "
        f"({'met' if speedup >= 10 else 'not met'})",
    ]


def run(base: str | Path = BASE, budget: float = 20.0, rounds: int = 3, out: Path | None = None):
    """Measure and write the page; ``base`` is a commit, or a folder holding an exported tree
    (``grasp_env``, ``agents``) to use as it is."""
    headless()
    head = Path(__file__).resolve().parent.parent
    with tempfile.TemporaryDirectory() as tmp:
        tree = base if isinstance(base, Path) else export(base, Path(tmp))
        runs = measure(tree, head, budget, rounds)
    body = report(runs, str(base), budget)
    title = "Scripted policy against an earlier commit"
    return write(out or OUT / "scripted_speedup.md", title, body)


def main(argv: list[str] | None = None) -> int:
    ap = parser(
        "benchmarks.scripted_speedup", __doc__, "scripted_speedup.md", quick="2 rounds of 3 s"
    )
    ap.add_argument(
        "--base", type=revision, default=BASE, help="the earlier commit (a revision git knows)"
    )
    ap.add_argument(
        "--budget", type=positive_float, default=20.0, help="seconds per side per round"
    )
    ap.add_argument("--rounds", type=positive_int, default=3, help="rounds")
    args = ap.parse_args(argv)
    budget, rounds = (3.0, 2) if args.quick else (args.budget, args.rounds)
    run(args.base, budget, rounds, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
