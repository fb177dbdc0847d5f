"""Success against one swept parameter of the env: the table, the plot and the generated page
of an evaluation played at several levels of it (``python -m agents.evaluate --friction
0,0.1,... --friction-page PATH``, or ``--uncertainty`` and ``--uncertainty-page``), from
:func:`agents.summary.summarize`'s rows."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.provenance import generated_header
from agents.summary import SUITE_TITLES


@dataclass(frozen=True)
class Sweep:
    """A swept env parameter: its rows' column (``key``), its symbol in the table's head, the
    plot's axis label, the page's subject (its title: "Success against <subject>") and the
    page's paragraph on how it is played."""

    key: str
    symbol: str
    axis: str
    subject: str
    how: str


FRICTION = Sweep(
    "friction", "mu", "Coulomb friction mu", "friction",
    "Each policy plays the same scenes, starts and seeds at each Coulomb coefficient `mu` "
    "(the env's `friction`, the same at every contact): a step whose hand motion the "
    "contacts could resist with that friction (`grasp_env.critical_friction` at most "
    "`mu`) jams, and the hand stays where it is; between such steps the object moves as "
    "without friction. So a policy succeeds at `mu` when it reaches the grasp by motions "
    "that friction `mu` cannot stop. Success is form closure off the support at the "
    "episode's last step, with its Wilson 95% interval; `test time` says what the policy "
    "calls when it plays ([results.md](results.md)). The test and what it leaves out: "
    "[friction.md](friction.md).",
)  # fmt: skip
UNCERTAINTY = Sweep(
    "uncertainty", "sigma", "vertex noise sigma (palm widths)", "shape uncertainty",
    "Each policy plays the same scenes, starts, seeds and perturbations at each level "
    "`sigma` (the env's `uncertainty`): the simulated object is the nominal one with every "
    "vertex moved by normal noise of standard deviation `sigma` palm widths (the resting "
    "edge along the support), while the policy is told the nominal object (the scripted "
    "planner plans on it and plays its plan open loop). Success is form closure off the "
    "support at the episode's last step, with its Wilson 95% interval; `test time` says "
    "what the policy calls when it plays ([results.md](results.md)). The set-up and where "
    "the planner breaks: [uncertainty.md](uncertainty.md).",
)  # fmt: skip
#: Every swept parameter: a sweep's table and plot keep the others at their lowest level.
SWEEPS = (FRICTION, UNCERTAINTY)


def levels_of(rows: list[dict[str, Any]], sweep: Sweep) -> list[float]:
    """The sweep's levels in the rows, in increasing order."""
    return sorted({r[sweep.key] for r in rows})


def swept_rows(rows: list[dict[str, Any]], sweep: Sweep) -> list[dict[str, Any]]:
    """The rows of the sweep: every other swept parameter at its lowest level."""
    lowest = {s.key: min(r[s.key] for r in rows) for s in SWEEPS if s is not sweep}
    return [r for r in rows if all(r[k] == v for k, v in lowest.items())]


#: What a sweep's table and plot can show at each level: the row keys of the value and its
#: 95% interval, and how the plot's axis names it.
MEASURES = {
    "success": ("success_rate", "success_ci_low", "success_ci_high", "success rate"),
    "grip": ("grip_W_mean", "grip_W_ci_low", "grip_W_ci_high", "y*/W over the successes"),
}


def _cell(r: dict[str, Any] | None, measure: str) -> str:
    value, low, high, _ = MEASURES[measure]
    if r is None or not math.isfinite(r.get(value, math.nan)):
        return "n/a"
    return f"{r[value]:.2f} ({r[low]:.2f}-{r[high]:.2f})"


def sweep_table(rows: list[dict[str, Any]], sweep: Sweep, measure: str = "success") -> str:
    """One markdown row per suite and policy: its success rate (Wilson 95% interval), or
    with ``measure="grip"`` its mean y*/W over the successes (bootstrap 95% interval), at
    each level of the sweep."""
    rows = swept_rows(rows, sweep)
    levels = levels_of(rows, sweep)
    head = "| suite | policy | test time | n | "
    head += " | ".join(f"{sweep.symbol} = {m:g}" for m in levels)
    lines = [head + " |", "| --- " * (4 + len(levels)) + "|"]
    cells: dict[tuple[str, str], dict[float, dict[str, Any]]] = {}
    for r in rows:
        cells.setdefault((r["suite"], r["policy"]), {})[r[sweep.key]] = r
    for (suite, policy), by_level in cells.items():
        first = next(iter(by_level.values()))
        rates = [_cell(by_level.get(m), measure) for m in levels]
        lines.append(
            f"| {suite} | {policy} | {first['test_time']} | {first['episodes']} | "
            + " | ".join(rates)
            + " |"
        )
    return "\n".join(lines) + "\n"


def sweep_plot(path: Path, rows: list[dict[str, Any]], sweep: Sweep) -> None:
    """Success rate (top row) and mean y*/W over the successes (bottom row) against the
    sweep's level, one column per suite, one line per policy, with the 95% intervals as
    bands."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = swept_rows(rows, sweep)
    suites = list(dict.fromkeys(r["suite"] for r in rows))
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    height = 6.6
    fig, axes = plt.subplots(2, len(suites), figsize=(4.2 * len(suites), height), squeeze=False)
    levels = levels_of(rows, sweep)
    pad = 0.05 * (max(levels) - min(levels) or 1.0)
    colors = {p: f"C{i % 10}" for i, p in enumerate(policies)}
    for row, measure in zip(axes, MEASURES, strict=True):
        value, low, high, axis = MEASURES[measure]
        for ax, suite in zip(row, suites, strict=True):
            for policy in policies:
                mine = sorted(
                    (r for r in rows if r["suite"] == suite and r["policy"] == policy
                     and math.isfinite(r.get(value, math.nan))),
                    key=lambda r: r[sweep.key],
                )  # fmt: skip
                if not mine:
                    continue
                x = [r[sweep.key] for r in mine]
                ax.plot(x, [r[value] for r in mine], marker="o", label=policy,
                        color=colors[policy])  # fmt: skip
                ax.fill_between(
                    x, [r[low] for r in mine], [r[high] for r in mine],
                    color=colors[policy], alpha=0.12,
                )  # fmt: skip
            ax.set_title(suite)
            ax.set_xlabel(sweep.axis)
            ax.set_xlim(min(levels) - pad, max(levels) + pad)  # every panel on the same levels
            if measure == "success":
                ax.set_ylim(-0.02, 1.02)
        row[0].set_ylabel(axis)
    handles, labels = axes[0][0].get_legend_handles_labels()
    ncol = min(len(policies), 4)
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    legend = (0.25 * math.ceil(len(policies) / ncol) + 0.15) / height  # its share of the figure
    fig.tight_layout(rect=(0, legend, 1, 1))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def sweep_page(
    rows: list[dict[str, Any]], sweep: Sweep, image: str, command: str, date: str, commit: str
) -> str:
    """The page: how the sweep is played, the table and the plot (``image``, relative to the
    page), with the date, the commit and the command."""
    suites = list(dict.fromkeys(r["suite"] for r in rows))
    lines = [
        f"# Success against {sweep.subject}",
        "",
        *generated_header(f"agents.evaluate --{sweep.key}-page", command, date, commit),
        sweep.how,
        "",
        "Suites: " + "; ".join(f"`{s}`, {SUITE_TITLES.get(s, s)}" for s in suites) + ".",
        "",
        sweep_table(rows, sweep).rstrip("\n"),
        "",
        "The grip of the successes, y\\*/W (mean, bootstrap 95% interval; `n/a` without a "
        "success):",
        "",
        sweep_table(rows, sweep, "grip").rstrip("\n"),
        "",
        f"![success and grip against {sweep.subject}]({image})",
    ]
    return "\n".join(lines) + "\n"
