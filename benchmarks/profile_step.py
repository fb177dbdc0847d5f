"""Where the time of one env step goes: a cProfile of random-action steps, by category.

Also profiled: the ``fig13`` closing motion of the work-precision benchmark (its 5 ms
target, benchmarks/README.md).

Every profiled function's own time (cProfile ``tottime``) is charged to the nearest
categorised function on its call path: a function matching a rule in :data:`PHASES` is its
own category; any other function (numpy, scipy, helpers) is charged to its callers, split in
proportion to the time spent under each caller. The simulator's move is one compiled call
(``grasp_env/sim``), which cProfile sees as a whole: its parts (LP, Newton, checks, events,
falls) are not split here; ``benchmarks/work_precision.py`` times the simulator alone. "LP
solve" is what is solved outside it (HiGHS on the reference path, the analysis), except
where a nearer category (y*) calls it.

cProfile slows Python-heavy code: the page gives the unprofiled us/step of the same run
beside the profiled total. ``profile.json`` keeps the numbers; ``--baseline`` with an older
``profile.json`` adds before/after columns.

Usage: ``python -m benchmarks.profile_step [--quick] [--baseline old.json]``
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import re
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym

import grasp_env
from benchmarks.common import (
    git_commit,
    headless,
    machine_line,
    median_time,
    page_main,
    table,
)
from benchmarks.throughput import RandomActions
from benchmarks.work_precision import closing_motion
from grasp_env.cli import existing_file, positive_int, read_text

#: ``(category, file regex, function-name regex)``; the first rule that matches wins.
PHASES: list[tuple[str, str, str]] = [
    ("info dict", r"frictionless_grasp\.py$|grasp_env/mechanics/contacts\.py$", r"_info|as_dict"),
    ("y* (grip objective)", r"grasp_env/mechanics/closure\.py$", r"^grip_objective$"),
    ("form closure test", r"grasp_env/(mechanics/closure|solvers/fastlp)\.py$", r"form_closure"),
    (
        "LP solve (fastlp / HiGHS, outside the simulator)",
        r"grasp_env/solvers/(fastlp|lp|simplex|motion_lp)\.py$",
        r"",
    ),
    ("compiled simulator (one call per move)", r"grasp_env/sim/", r""),
    ("simulator shell (arguments, State)", r"grasp_env/simulator\.py$", r""),
    (
        "placement (world poses, contact evaluate)",
        r"grasp_env/(mechanics/contacts|core/kinematics|core/geometry)\.py$",
        r"",
    ),
    ("observation", r"frictionless_grasp\.py$", r"_get_obs|_in_palm_frame"),
    ("reward", r"frictionless_grasp\.py$", r"_get_rew|_potential"),
    ("reset (episode starts)", r"frictionless_grasp\.py$", r"^reset$|_preliftoff|_perturb"),
    ("env step (action check, analysis)", r"frictionless_grasp\.py$", r""),
    ("gymnasium wrappers", r"gymnasium/", r""),
    ("benchmark loop", r"benchmarks/", r""),
]
_RULES = [(name, re.compile(f), re.compile(fn)) for name, f, fn in PHASES]
OTHER = "other (uncharged)"
PLAIN_REPEAT = 3  #: unprofiled runs of a workload (median)


def _own_category(func: tuple[str, int, str]) -> str | None:
    path, _, name = func
    path = path.replace("\\", "/")
    for category, file_re, name_re in _RULES:
        if file_re.search(path) and name_re.search(name):
            return category
    return None


def categorise(stats: dict) -> dict[str, float]:
    """Seconds of own time per category, from ``pstats.Stats(...).stats``."""
    memo: dict = {}

    def shares(func, seen: frozenset) -> dict[str, float]:
        if func in memo:
            return memo[func]
        own = _own_category(func)
        if own is not None:
            out = {own: 1.0}
        else:
            callers = stats[func][4] if func in stats else {}
            weights = {c: edge[3] for c, edge in callers.items() if c not in seen}
            total = sum(weights.values())
            if total <= 0.0:
                out = {OTHER: 1.0}
            else:
                out = defaultdict(float)
                for caller, wgt in weights.items():
                    for cat, frac in shares(caller, seen | {func}).items():
                        out[cat] += frac * wgt / total
                out = dict(out)
        memo[func] = out
        return out

    seconds: dict[str, float] = defaultdict(float)
    for func, (_, _, tt, _, _) in stats.items():
        for cat, frac in shares(func, frozenset()).items():
            seconds[cat] += tt * frac
    return dict(seconds)


def _step_loop(kwargs: dict, steps: int) -> Callable[[], None]:
    """A workload: ``steps`` random-action steps of a new env from ``reset(seed=0)``."""
    env = gym.make("FrictionlessGrasp-v0", **kwargs)

    def work() -> None:
        policy = RandomActions(env.action_space, seed=0)
        obs, _ = env.reset(seed=0)
        for _ in range(steps):
            obs, _, terminated, truncated, _ = env.step(policy.act(obs))
            if terminated or truncated:
                obs, _ = env.reset()

    return work


def _closing() -> None:
    closing_motion(grasp_env.Simulator("fig13"))


def profile(work: Callable[[], object], units: int) -> dict:
    """Unprofiled (median of :data:`PLAIN_REPEAT` calls) and profiled us per unit of ``work``
    (one call covers ``units``), and us per unit by category."""
    plain = median_time(work, PLAIN_REPEAT)[0] / units
    prof = cProfile.Profile()
    prof.enable()
    work()
    prof.disable()
    stats = pstats.Stats(prof).stats
    seconds = categorise(stats)
    top = sorted(stats.items(), key=lambda kv: -kv[1][2])[:12]
    return {
        "units": units,
        "plain_us": plain * 1e6,
        "profiled_us": sum(seconds.values()) / units * 1e6,
        "calls": sum(st[1] for st in stats.values()) / units,
        "categories": {k: v / units * 1e6 for k, v in seconds.items()},
        "top": [
            (f"{Path(f[0]).name}:{f[1]}({f[2]})", s[1] / units, s[2] / units * 1e6) for f, s in top
        ],
    }


def _section(title: str, unit: str, res: dict, before: dict | None) -> list[str]:
    cats = sorted(res["categories"].items(), key=lambda kv: -kv[1])
    total = res["profiled_us"]
    header = ["category", f"% of {unit}", f"us/{unit} (profiled)"]
    rows = []
    if before is not None:
        header += [f"before us/{unit}", "after / before"]
    for cat, us in cats:
        row = [cat, f"{100 * us / total:.1f}", f"{us:,.0f}"]
        if before is not None:
            old = before["categories"].get(cat, 0.0)
            row += [f"{old:,.0f}", f"{us / old:.2f}" if old > 0 else "new"]
        rows.append(row)
    total_row = ["**total**", "100.0", f"**{total:,.0f}**"]
    if before is not None:
        old_total = before["profiled_us"]
        total_row += [f"{old_total:,.0f}", f"{total / old_total:.2f}"]
    rows.append(total_row)
    plain = f"Unprofiled: **{res['plain_us']:,.0f} us/{unit}**"
    if before is not None:
        ratio = res["plain_us"] / before["plain_us"]
        plain += f" (before: {before['plain_us']:,.0f}, after / before {ratio:.2f})"
    return [
        f"## {title}",
        "",
        plain + f"; profiled: {total:,.0f} us/{unit}; {res['calls']:,.0f} function calls "
        f"(Python and C) per {unit}.",
        "",
        *table(header, rows),
        "",
        "Top functions by own time:",
        "",
        *table(
            ["function", f"calls/{unit}", f"own us/{unit}"],
            [(f"`{n}`", f"{c:.1f}", f"{us:,.0f}") for n, c, us in res["top"]],
        ),
        "",
    ]


#: Env configurations profiled: name -> ``gymnasium.make`` kwargs.
CONFIGS = {"default": {}, "palm_control": {"palm_control": True}}


def run(
    quick: bool,
    out: Path,
    steps: int | None = None,
    baseline: Path | None = None,
    closing: bool = True,
) -> Path:
    """Profile the env configurations (and the fig13 closing motion) and write
    ``profile.md`` and ``profile.json``."""
    headless()
    steps = steps or (40 if quick else 400)
    before = json.loads(baseline.read_text()) if baseline else {}
    sections, results = [], {}
    for name, kwargs in CONFIGS.items():
        results[name] = profile(_step_loop(kwargs, steps), steps)
        title = f"{name}: `{kwargs or 'default kwargs'}`, {steps} random-action steps"
        sections.append((name, title, "step"))
        print(f"{name}: {results[name]['plain_us']:,.0f} us/step unprofiled")
    if closing:
        results["fig13_closing"] = profile(_closing, 1)
        title = "fig13 closing motion (`benchmarks.work_precision.closing_motion`, defaults)"
        sections.append(("fig13_closing", title, "motion"))
    stamp = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    record = {"commit": git_commit(), "time": stamp, **results}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(record, indent=1))
    lines = [
        "# Profile of one env step",
        "",
        machine_line(),
        "",
        f"Commit {record['commit']}, {stamp}."
        + (f" Before: {before.get('commit')}, {before.get('time')}." if before else ""),
        "Own time of each function charged to its nearest categorised caller "
        "(`benchmarks/profile_step.py`, `PHASES`); `render_mode=None`.",
        "",
    ]
    for name, title, unit in sections:
        lines += _section(title, unit, results[name], before.get(name))
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")
    return out


def baseline_file(text: str) -> Path:
    """An ``argparse`` type: a ``profile.json`` (an object of JSON), read before any
    profiling."""
    path = existing_file(text)
    try:
        record = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"{text!r} is not JSON: {exc}") from None
    except ValueError as exc:  # unreadable, not UTF-8
        raise argparse.ArgumentTypeError(str(exc)) from None
    if not isinstance(record, dict):
        raise argparse.ArgumentTypeError(f"{text!r} is not a profile.json: not a JSON object")
    return path


#: ``run``'s options on the command line: name, type, help.
OPTIONS = (
    ("steps", positive_int, "random-action steps per configuration"),
    ("baseline", baseline_file, "an older profile.json to compare with"),
)


def main(argv: list[str] | None = None) -> int:
    return page_main(argv, run, "profile.md", "40 steps per configuration", OPTIONS)


if __name__ == "__main__":
    raise SystemExit(main())
