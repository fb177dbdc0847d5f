"""Success against friction: the table, the plot and the generated page of an evaluation
played at several Coulomb coefficients (``python -m agents.evaluate --friction 0,0.1,...
--friction-page PATH``), from :func:`agents.summary.summarize`'s rows."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from agents.provenance import generated_header
from agents.summary import SUITE_TITLES


def frictions_of(rows: list[dict[str, Any]]) -> list[float]:
    """The friction levels of the rows, in increasing order."""
    return sorted({r["friction"] for r in rows})


def friction_table(rows: list[dict[str, Any]]) -> str:
    """One markdown row per suite and policy: its success rate (Wilson 95% interval) at each
    friction level."""
    levels = frictions_of(rows)
    head = "| suite | policy | test time | n | " + " | ".join(f"mu = {m:g}" for m in levels)
    lines = [head + " |", "| --- " * (4 + len(levels)) + "|"]
    cells: dict[tuple[str, str], dict[float, dict[str, Any]]] = {}
    for r in rows:
        cells.setdefault((r["suite"], r["policy"]), {})[r["friction"]] = r
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


def friction_plot(path: Path, rows: list[dict[str, Any]]) -> None:
    """Success rate against the friction coefficient, one panel per suite, one line per
    policy, with the 95% intervals as bands."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    suites = list(dict.fromkeys(r["suite"] for r in rows))
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    fig, axes = plt.subplots(1, len(suites), figsize=(4.2 * len(suites), 3.6), squeeze=False)
    for ax, suite in zip(axes[0], suites, strict=True):
        for policy in policies:
            mine = sorted(
                (r for r in rows if r["suite"] == suite and r["policy"] == policy),
                key=lambda r: r["friction"],
            )
            if not mine:
                continue
            mu = [r["friction"] for r in mine]
            line = ax.plot(mu, [r["success_rate"] for r in mine], marker="o", label=policy)[0]
            ax.fill_between(
                mu, [r["success_ci_low"] for r in mine], [r["success_ci_high"] for r in mine],
                color=line.get_color(), alpha=0.12,
            )  # fmt: skip
        ax.set_title(suite)
        ax.set_xlabel("Coulomb friction mu")
        ax.set_ylim(-0.02, 1.02)
    axes[0][0].set_ylabel("success rate")
    handles, labels = axes[0][0].get_legend_handles_labels()
    ncol = min(len(policies), 4)
    fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.07 * math.ceil(len(policies) / ncol) + 0.03, 1, 1))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def friction_page(
    rows: list[dict[str, Any]], image: str, command: str, date: str, commit: str
) -> str:
    """The page: how friction is played, the table and the plot (``image``, relative to the
    page), with the date, the commit and the command."""
    suites = list(dict.fromkeys(r["suite"] for r in rows))
    lines = [
        "# Success against friction",
        "",
        *generated_header("agents.evaluate --friction-page", command, date, commit),
        "Each policy plays the same scenes, starts and seeds at each Coulomb coefficient `mu` "
        "(the env's `friction`, the same at every contact): a step whose hand motion the "
        "contacts could resist with that friction (`grasp_env.critical_friction` at most "
        "`mu`) jams, and the hand stays where it is; between such steps the object moves as "
        "without friction. So a policy succeeds at `mu` when it reaches the grasp by motions "
        "that friction `mu` cannot stop. Success is form closure off the support at the "
        "episode's last step, with its Wilson 95% interval; `test time` says what the policy "
        "calls when it plays ([results.md](results.md)). The test and what it leaves out: "
        "[friction.md](friction.md).",
        "",
        "Suites: " + "; ".join(f"`{s}`, {SUITE_TITLES.get(s, s)}" for s in suites) + ".",
        "",
        friction_table(rows).rstrip("\n"),
        "",
        f"![success against friction]({image})",
    ]
    return "\n".join(lines) + "\n"
