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


def sweep_table(rows: list[dict[str, Any]], sweep: Sweep) -> str:
    """One markdown row per suite and policy: its success rate (Wilson 95% interval) at each
    level of the sweep."""
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
        rates = [
            f"{r['success_rate']:.2f} ({r['success_ci_low']:.2f}-{r['success_ci_high']:.2f})"
            if (r := by_level.get(m)) else "n/a"
            for m in levels
        ]  # fmt: skip
        lines.append(
            f"| {suite} | {policy} | {first['test_time']} | {first['episodes']} | "
            + " | ".join(rates)
            + " |"
        )
    return "\n".join(lines) + "\n"


def sweep_plot(path: Path, rows: list[dict[str, Any]], sweep: Sweep) -> None:
    """Success rate against the sweep's level, one panel per suite, one line per policy, with
    the 95% intervals as bands."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = swept_rows(rows, sweep)
    suites = list(dict.fromkeys(r["suite"] for r in rows))
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    fig, axes = plt.subplots(1, len(suites), figsize=(4.2 * len(suites), 3.6), squeeze=False)
    for ax, suite in zip(axes[0], suites, strict=True):
        for policy in policies:
            mine = sorted(
                (r for r in rows if r["suite"] == suite and r["policy"] == policy),
                key=lambda r: r[sweep.key],
            )
            if not mine:
                continue
            x = [r[sweep.key] for r in mine]
            line = ax.plot(x, [r["success_rate"] for r in mine], marker="o", label=policy)[0]
            ax.fill_between(
                x, [r["success_ci_low"] for r in mine], [r["success_ci_high"] for r in mine],
                color=line.get_color(), alpha=0.12,
            )  # fmt: skip
        ax.set_title(suite)
        ax.set_xlabel(sweep.axis)
        ax.set_ylim(-0.02, 1.02)
    axes[0][0].set_ylabel("success rate")
    handles, labels = axes[0][0].get_legend_handles_labels()
    ncol = min(len(policies), 4)
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.07 * math.ceil(len(policies) / ncol) + 0.03, 1, 1))
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
        f"![success against {sweep.subject}]({image})",
    ]
    return "\n".join(lines) + "\n"
