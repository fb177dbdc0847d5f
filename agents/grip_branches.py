"""The grip adjustment of a grasp plan like the paper's Fig. 14 (:func:`write_branch_plot`):
``y*`` along every four-contact branch the adjustment evaluated (``Plan.grip_probes``)
against finger 1's angle, as change relative to ``y*`` at the start of the adjustment, on an
axis zoomed to the adjustment, the branch it followed highlighted with its steps and the
optimum it stopped at; beside it, for context, ``y*`` on the branches through the final
grasp over a wider range of ``q1``. Drawn for ``python -m agents.scripted``; the plot needs
the ``viz`` extra (matplotlib).
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from agents.plan_figures import contact_name, viz
from grasp_env import planning
from grasp_env.simulator import Simulator

#: Half-width (rad) of the finger-1 range of the context panel of the Fig. 14 plot about
#: the final grasp.
BRANCH_HALF_WIDTH = 0.15
#: Samples of each branch curve traced across the zoomed panel of the Fig. 14 plot.
BRANCH_SAMPLES = 161


def _branch_key(plan: planning.Plan, probe: planning.BranchProbe) -> tuple:
    contacts = plan.steps[probe.step].state.contacts
    return tuple(sorted(contacts[k].key for k in probe.kept))


def _branch_label(plan: planning.Plan, probe: planning.BranchProbe) -> str:
    """The contacts a branch keeps (numbered as in the state it was evaluated from) and the
    ones it breaks."""
    contacts = plan.steps[probe.step].state.contacts
    kept = ", ".join(
        f"{k + 1} {contact_name(contacts[k].body, contacts[k].kind)}" for k in probe.kept
    )
    dropped = [k + 1 for k in range(len(contacts)) if k not in probe.kept]
    if not dropped:
        return f"keeps all four contacts ({kept})"
    return f"breaks contact {', '.join(map(str, dropped))}; keeps {kept}"


def trace_branch(
    sim: Simulator, state, kept: tuple[int, ...], q_lo: float, q_hi: float, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(q1, y*)`` along the four-contact branch through ``state`` keeping contacts
    ``kept``, traced by continuation from ``state`` towards ``q_lo`` and ``q_hi`` at ``n``
    angles across that range, as far as the branch stays valid."""
    keys = [state.contacts[k].key for k in kept]
    br = planning.FourContactBranch(sim, keys, state.hand, kept)
    q0 = float(state.hand[3])
    grid = np.linspace(q_lo, q_hi, n)
    pts = {}
    for side in (grid[grid >= q0], grid[grid < q0][::-1]):
        z = np.array([*state.object_pose, state.hand[4]])
        for q1 in side:
            y, z_new = br.grip(float(q1), z)
            if z_new is None:
                break
            z = z_new
            pts[float(q1)] = float(y)
    q = np.array(sorted(pts))
    return q, np.array([pts[x] for x in q])


def write_branch_plot(sim: Simulator, plan: planning.Plan, path: Path) -> list[dict]:
    """The grip adjustment like the paper's Fig. 14, as a PNG; returns the branches drawn.

    Left: ``y*`` along each four-contact branch the adjustment evaluated (one curve per
    branch, traced across the adjustment's range of ``q1``), as the change relative to
    ``y*`` where the adjustment started (percent), the branch it followed highlighted, the
    adjustment's steps as squares (joined in order) and the optimum it stopped at as a star.
    Right, for context: ``y*`` (per object weight) along the branches through the final
    grasp within ``BRANCH_HALF_WIDTH`` of its ``q1``, the left panel's range shaded.

    Each returned dict has the branch's ``label``, the contacts it keeps (``kept``, indices
    into the contacts of the state it was first evaluated from, ``step``), whether the
    adjustment followed it, and its traced ``q1`` and ``grip`` samples.
    """
    plt = viz("matplotlib.pyplot")
    final = plan.steps[-1].state
    weight = final.scene.object_weight
    probes = plan.grip_probes
    fig, (ax, ctx) = plt.subplots(
        1, 2, figsize=(11.0, 5.6), dpi=110, gridspec_kw={"width_ratios": [3, 2]}
    )
    branches: list[dict] = []
    start = probes[0].step if probes else len(plan.steps) - 1
    y_ref = plan.steps[start].grip
    if not math.isfinite(y_ref):
        y_ref = plan.steps[-1].grip

    def rel(y) -> np.ndarray:
        return (np.asarray(y, dtype=float) / y_ref - 1.0) * 100.0

    path_steps = [(i, plan.steps[i]) for i in range(start, len(plan.steps))]
    path_steps = [(i, st) for i, st in path_steps if math.isfinite(st.grip)]
    q_all = [float(st.state.hand[3]) for _, st in path_steps]
    for p in probes:
        q_all.extend(p.q1)
    if q_all:
        q_lo, q_hi = min(q_all), max(q_all)
        pad = max(0.25 * (q_hi - q_lo), 2e-3)
        q_lo, q_hi = q_lo - pad, q_hi + pad
    else:
        q_lo = q_hi = float(final.hand[3])

    # one curve per branch (the same contacts kept = the same branch), in first-seen order
    seen: dict[tuple, dict] = {}
    for p in probes:
        key = _branch_key(plan, p)
        if key not in seen:
            seen[key] = {
                "label": _branch_label(plan, p),
                "kept": p.kept,
                "step": p.step,
                "followed": False,
                "probes": [],
            }
        seen[key]["probes"].append(p)
        seen[key]["followed"] |= p.chosen is not None
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    others = iter(colors[1:] * 4)
    for b in seen.values():
        q, y = trace_branch(sim, plan.steps[b["step"]].state, b["kept"], q_lo, q_hi, BRANCH_SAMPLES)
        b["q1"], b["grip"] = q.tolist(), y.tolist()
        color = colors[0] if b["followed"] else next(others)
        label = ("followed: " if b["followed"] else "not followed: ") + b["label"]
        lw, style = (2.6, "-") if b["followed"] else (1.4, "--")
        ax.plot(q, rel(y), style, color=color, lw=lw, label=label, zorder=2)
        del b["probes"]
        branches.append(b)
    if path_steps:
        q = [float(st.state.hand[3]) for _, st in path_steps]
        y = rel([st.grip for _, st in path_steps])
        ax.plot(q, y, "-", color="0.25", lw=0.8, zorder=4)
        ax.plot(
            q, y, "s", color="k", mfc="white", ms=7, zorder=5, label="adjustment steps (in order)"
        )
        i0, i1 = path_steps[0][0], path_steps[-1][0]
        ax.annotate(
            f"step {i0} (form closure)" if i0 == plan.form_closure_step() else f"step {i0}",
            (q[0], y[0]),
            textcoords="offset points",
            xytext=(-8, 8),
            ha="right",
            fontsize=10,
        )
        ax.plot(q[-1], y[-1], "*", color="crimson", ms=18, zorder=6, label="optimum reached")
        ax.annotate(
            f"step {i1}: {y[-1]:+.3g} %",
            (q[-1], y[-1]),
            textcoords="offset points",
            xytext=(0, -22),
            ha="center",
            fontsize=10,
            color="crimson",
        )
        labelled = [q[0], q[-1]]
        for k, (qi, yi) in enumerate(zip(q, y, strict=True)):
            # number the steps in between where the numbers do not crowd
            if 0 < k < len(q) - 1 and min(abs(qi - x) for x in labelled) > 0.04 * (q_hi - q_lo):
                labelled.append(qi)
                ax.annotate(
                    str(path_steps[k][0]),
                    (qi, yi),
                    textcoords="offset points",
                    xytext=(0, 7),
                    ha="center",
                    fontsize=7,
                    color="0.3",
                )
    if q_lo < q_hi:
        ax.set_xlim(q_lo, q_hi)
    ys = [v for b in branches for v in rel(b["grip"]).tolist()]
    if path_steps:
        ys.extend(rel([st.grip for _, st in path_steps]).tolist())
    if ys:
        lo, hi = min(ys), max(ys)
        span = max(hi - lo, 1e-6)
        ax.set_ylim(lo - 0.15 * span, hi + 0.1 * span)
    ax.ticklabel_format(axis="both", useOffset=False)
    ax.set_xlabel("finger 1 angle q1 (rad)", fontsize=11)
    ax.set_ylabel(f"change of y* since step {start} (%)", fontsize=11)
    n_br = len(branches)
    ax.set_title(
        f"grip adjustment: {n_br} four-contact branch{'es' if n_br != 1 else ''} evaluated",
        fontsize=12,
    )
    if not branches:
        ax.text(
            0.5,
            0.5,
            "no four-contact branch keeps form closure",
            ha="center",
            transform=ax.transAxes,
        )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=9, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)

    # context: the branches through the final grasp over a wider range
    curves = planning.grip_curves(sim, final, half_width=BRANCH_HALF_WIDTH)
    for c in curves:
        if not c["q1"]:
            continue
        dropped = ", ".join(str(k + 1) for k in c["dropped"])
        label = f"breaks contact {dropped}" if dropped else "keeps all four contacts"
        label += "" if c["form_closure"] else " (no form closure)"
        style = "-" if c["form_closure"] else ":"
        ctx.plot(c["q1"], np.asarray(c["grip"]) / weight, style, lw=1.6, label=label)
    if q_lo < q_hi:
        ctx.axvspan(q_lo, q_hi, color="gold", alpha=0.35, label="left panel's range")
    ctx.plot(final.hand[3], plan.steps[-1].grip / weight, "*", color="crimson", ms=14)
    ctx.set_xlabel("finger 1 angle q1 (rad)", fontsize=11)
    ctx.set_ylabel("y* / object weight", fontsize=11)
    ctx.set_title(f"around the final grasp (q1 ± {BRANCH_HALF_WIDTH:g} rad)", fontsize=12)
    ctx.xaxis.set_major_locator(plt.MaxNLocator(4))
    ctx.ticklabel_format(axis="y", useOffset=False)
    ctx.grid(alpha=0.3)
    ctx.legend(fontsize=9, loc="upper center", bbox_to_anchor=(0.5, -0.16))
    change = rel(plan.steps[-1].grip).item() if math.isfinite(plan.steps[-1].grip) else math.nan
    end = "a local minimum" if "local minimum" in plan.message else "where it stopped"
    fig.suptitle(
        textwrap.fill(
            f"{final.scene.name}: the grip adjustment changes y* by {change:+.3g} %, from step "
            f"{start} to {end} at step {len(plan.steps) - 1}",
            95,
        ),
        fontsize=13,
    )
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return branches
