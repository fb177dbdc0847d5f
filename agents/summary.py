"""The evaluation's summary: per suite and policy, success rates with Wilson intervals and
means with bootstrap intervals (:func:`summarize`), as a markdown table, a CSV file and bar
charts, and the results page (``docs/results.md``); the episodes' GIF."""

from __future__ import annotations

import csv
import itertools
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.episodes import GIF_EVERY, GIF_SCENE
from agents.models import TEST_TIMES
from agents.provenance import generated_header

if TYPE_CHECKING:
    from agents.episodes import Episode

#: Resamples of the bootstrap intervals.
BOOTSTRAP_SAMPLES = 2000
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
    """One row per (friction, uncertainty, suite, policy): rates with Wilson CIs, means with
    bootstrap CIs,
    ``test_time``, what the policy calls at test time (``test_times``, by policy name; "" for
    a policy it does not name), and ``friction``, the Coulomb coefficient the episodes were
    played at (0: the frictionless task), and ``uncertainty``, the standard deviation of the
    vertices' perturbation (0: the shape known exactly).

    Suites: the paper's scene alone (``fig13``), all bundled scenes (left out where fig13 is
    the only one: its rows would repeat fig13's), the held-out shapes in the default and the
    wide ranges and from the planner's placement, fig13 from perturbed starts.
    """
    rows = []
    for level in sorted({(e.friction, e.uncertainty) for e in episodes}):
        at = [e for e in episodes if (e.friction, e.uncertainty) == level]
        labels = {"friction": level[0], "uncertainty": level[1]}
        rows += [r | labels for r in _summarize_one(at, test_times)]
    return rows


def _summarize_one(
    episodes: list[Episode], test_times: dict[str, str] | None
) -> list[dict[str, Any]]:
    """:func:`summarize` of episodes played at one friction and uncertainty."""
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


#: The policy the shape-by-shape comparison measures the others against.
REFERENCE = "scripted"
#: The second reference, where it played (``agents.evaluate --planner-in-place``): the
#: planner lifting from where the env puts the hand, which tells the shapes a policy grasps
#: only by finding a better placement than the start's from those it misses from there.
IN_PLACE_REFERENCE = "scripted_in_place"
#: How the pages name each reference.
REFERENCE_NAMES = {REFERENCE: "the planner", IN_PLACE_REFERENCE: "the planner in place"}
#: The suites paired shape by shape (one episode per seed and policy).
PAIRED_SUITES = ("heldout", "wide", "lift", "perturbed")
#: y*/W differences within this are counted as equal (the same grasp, up to rounding).
GRIP_EQUAL = 1e-9


def paired_rows(
    episodes: list[Episode], test_times: dict[str, str] | None = None,
    reference: str = REFERENCE,
) -> list[dict[str, Any]]:  # fmt: skip
    """Every policy against ``reference`` on the same seeds, per (friction, uncertainty,
    suite) of :data:`PAIRED_SUITES`: the shapes only one of them grasps, and on the shapes
    both grasp (a finite ``y*``) the mean difference of ``y*/W`` (policy minus reference)
    with its percentile bootstrap 95% interval, and on how many it is lower, equal (within
    :data:`GRIP_EQUAL`) or higher. Empty where ``reference`` did not play."""
    test_times = test_times or {}
    groups: dict[tuple, list[Episode]] = {}
    for e in episodes:
        if e.suite in PAIRED_SUITES:
            groups.setdefault((e.friction, e.uncertainty, e.suite, e.policy), []).append(e)
    rows = []
    levels = dict.fromkeys(key[:3] for key in groups)
    policies = list(dict.fromkeys(key[3] for key in groups if key[3] != reference))
    for (mu, sigma, suite), policy in itertools.product(levels, policies):
        planner = {e.seed: e for e in groups.get((mu, sigma, suite, reference), ())}
        pairs = [
            (e, planner[e.seed])
            for e in groups.get((mu, sigma, suite, policy), ())
            if e.seed in planner
        ]
        if not pairs:
            continue
        diffs = [
            a.grip_W - b.grip_W
            for a, b in pairs
            if a.success and b.success and math.isfinite(a.grip_W) and math.isfinite(b.grip_W)
        ]
        lo, hi = bootstrap_mean(diffs)
        rows.append(
            {
                "suite": suite,
                "policy": policy,
                "test_time": test_times.get(policy, ""),
                "reference": reference,
                "episodes": len(pairs),
                "policy_only": sum(a.success and not b.success for a, b in pairs),
                "reference_only": sum(b.success and not a.success for a, b in pairs),
                "both": len(diffs),
                "grip_W_diff_mean": float(np.mean(diffs)) if diffs else math.nan,
                "grip_W_diff_ci_low": lo,
                "grip_W_diff_ci_high": hi,
                "lower": sum(d < -GRIP_EQUAL for d in diffs),
                "equal": sum(abs(d) <= GRIP_EQUAL for d in diffs),
                "higher": sum(d > GRIP_EQUAL for d in diffs),
                "friction": mu,
                "uncertainty": sigma,
            }
        )
    return rows


def paired_table(rows: list[dict[str, Any]], against: str = "the planner") -> str:
    """:func:`paired_rows` (of one reference, named ``against``) as a markdown table."""
    lines = [
        f"| suite | policy | test time | n | grasped by it alone | by {against} alone "
        f"| both grasp | y*/W minus {against}'s, mean (95% CI) | lower / equal / higher |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        diff = EMPTY
        if r["both"]:
            diff = (
                f"{r['grip_W_diff_mean']:+.2f} ({r['grip_W_diff_ci_low']:+.2f} to "
                f"{r['grip_W_diff_ci_high']:+.2f})"
            )
        suite = suite_label(r)
        lines.append(
            f"| {suite} | {r['policy']} | {r['test_time']} | {r['episodes']} "
            f"| {r['policy_only']} | {r['reference_only']} | {r['both']} | {diff} "
            f"| {r['lower']} / {r['equal']} / {r['higher']} |"
        )
    return "\n".join(lines) + "\n"


#: A summary cell with nothing to show (no success to average, no episode that reached closure).
EMPTY = "n/a"
#: The swept env parameters a row's suite is labelled with where not 0: column and symbol.
LEVELS = (("friction", "mu"), ("uncertainty", "sigma"))
#: The summary table's columns: header and alignment row.
TABLE_HEAD = (
    "| suite | policy | test time | n | success (95% CI) | y*/W mean ± sd (95% CI) "
    "| steps to closure (95% CI) | drops | jams | errors |\n"
    "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n"
)


def suite_label(row: dict[str, Any]) -> str:
    """A row's suite, with the swept levels it was played at where not 0 (``mu``,
    ``sigma``)."""
    levels = [f"{symbol} {row[key]:g}" for key, symbol in LEVELS if row.get(key)]
    return f"{row['suite']} ({', '.join(levels)})" if levels else row["suite"]


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
        suite = suite_label(r)
        lines.append(
            f"| {suite} | {r['policy']} | {r['test_time']} | {r['episodes']} | {success} "
            f"| {grip} | {closure} | {r['drops']} | {r['jams']} | {r['errors']} |"
        )
    return "\n".join(lines) + "\n"


def results_page(
    rows: list[dict[str, Any]], command: str, date: str, commit: str,
    training: str = "training.md", paired: list[dict[str, Any]] | None = None,
) -> str:  # fmt: skip
    """The results page (``docs/results.md``): one table per suite, the date, the commit and
    the command that produced it, and which rows are network-only; under a seeded suite's
    table, its rows of ``paired`` (:func:`paired_rows`: each policy against the planner,
    shape by shape). ``training``: the link from the page to ``docs/training.md``, which
    explains the metrics."""
    network = list(dict.fromkeys(r["policy"] for r in rows if r["test_time"] == "network"))
    others = {
        level: list(dict.fromkeys(r["policy"] for r in rows if r["test_time"] == level))
        for level in TEST_TIMES[1:]
    }
    lines = [
        "# Results",
        "",
        *generated_header("agents.evaluate --results-page", command, date, commit),
        "Every policy meets the same scenes, starts and seeds; success is form closure off the "
        "support at the episode's last step, with its Wilson 95% interval; y\\*/W (the grip "
        "objective in object weights) is over the successes, with a bootstrap 95% interval of "
        "the mean; `n/a` where there is nothing to average. The metrics, suites and policies: "
        f"[training.md]({training}#evaluation).",
        "",
        "**Test time** says what a policy calls when it plays: `network`, its network alone "
        "on the env's observation (`random`: nothing); `planner`, the scripted planner, which "
        "plans on the exact model of the scene (its fallback searches included); `simulator`, "
        "also the exact simulator on copies of the env's state beyond the env's own step. "
        "What a suite's env does for every policy alike (the `lift` suite's start at the "
        "planner's placement) is not counted. A model plays the mean of its policy's "
        "distribution; a row `ppo_<name>_sampled` is the same network playing actions drawn "
        "from it, seeded with the episode's seed (`--sampled`). A row `scripted_in_place` "
        "(`--planner-in-place`) is the planner lifting from where the env puts the hand, "
        "without re-placing it or exploring.",
        "",
        f"Network-only rows: {_names(network)}.",
    ]
    for level, names in others.items():
        if names:
            lines.append(f"Rows of `{level}` policies: {_names(names)}.")
    for suite in dict.fromkeys(r["suite"] for r in rows):
        table = markdown_table([r for r in rows if r["suite"] == suite])
        lines += ["", f"## `{suite}`: {SUITE_TITLES.get(suite, suite)}", "", table.rstrip("\n")]
        for reference, name in REFERENCE_NAMES.items():
            against = [
                r for r in paired or () if r["suite"] == suite and r["reference"] == reference
            ]
            if against:
                lines += [
                    "",
                    f"Against {name} (`{reference}`), shape by shape (the same seeds): the "
                    "shapes one of them grasps and the other does not, and on the shapes both "
                    "grasp the difference of y\\*/W with a bootstrap 95% interval of its mean:",
                    "",
                    paired_table(against, name).rstrip("\n"),
                ]
    return "\n".join(lines) + "\n"


#: The suites of the results page that the README shows, and the markers of its block.
README_SUITES = ("heldout", "lift", "perturbed")
README_BEGIN = (
    "<!-- Results block: written from the results page by agents.evaluate --readme; "
    "regenerate rather than edit. -->"
)
README_END = "<!-- End of the results block. -->"


def readme_results(page: str, link: str, suites: tuple[str, ...] = README_SUITES) -> str:
    """The README's results block, taken from the results page's text ``page`` (linked as
    ``link``): where and when it was generated, which rows are network-only, and the tables
    of ``suites``, one a suite, as the page has them (its comparison with the planner, shape
    by shape, stays on the page)."""
    lines = page.splitlines()
    generated = next(line for line in lines if line.startswith("Generated on "))
    heads = [i for i, line in enumerate(lines) if line.startswith("## ")] + [len(lines)]
    out = [
        README_BEGIN,
        f"From [{link.rsplit('/', 1)[-1]}]({link}), "
        + generated[0].lower()
        + generated[1:].removesuffix(" by:")
        + ".",
        "",
        *(line for line in lines if line.startswith("Network-only rows:")),
    ]
    for suite in suites:
        for start, end in itertools.pairwise(heads):
            if lines[start].startswith(f"## `{suite}`:"):
                first = next(i for i in range(start, end) if lines[i].startswith("| "))
                table = itertools.takewhile(lambda line: line.startswith("| "), lines[first:end])
                out += ["", *table]
    return "\n".join([*out, README_END])


def update_readme(readme: Path, page: Path, link: str) -> None:
    """Replace the results block of ``readme`` (between :data:`README_BEGIN` and
    :data:`README_END`) with :func:`readme_results` of ``page``.

    Raises:
        ValueError: ``readme`` has no such block.
    """
    text = readme.read_text()
    begin, end = text.find(README_BEGIN), text.find(README_END)
    if begin < 0 or end < begin:
        raise ValueError(f"{readme} has no results block ({README_BEGIN!r} ... {README_END!r})")
    block = readme_results(page.read_text(), link)
    readme.write_text(text[:begin] + block + text[end + len(README_END) :])


def _names(names: list[str]) -> str:
    return ", ".join(f"`{n}`" for n in names) if names else "none"


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
