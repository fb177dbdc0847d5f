"""Figures of a grasp plan: the filmstrip (like the paper's Fig. 13), the grip-adjustment
branch plot (like Fig. 14) and an animated GIF; used by ``python -m agents.scripted``.

* :func:`write_filmstrip`: frames at the steps where something happens (the start, the
  tipping, lift-off, contact changes, a constrained fall, form closure, the start of grip
  adjustment, the final grasp; :func:`plan_events`), the rest of the frames where the bodies
  move most (:func:`frame_indices`), each under a two-line title (step and event; phase and
  ``y*``), with a legend of the drawing's colours and marks below.
* :func:`write_branch_plot`: ``y*`` along every four-contact branch the grip adjustment
  evaluated (``Plan.grip_probes``) against finger 1's angle, as change relative to ``y*`` at
  the start of the adjustment, on an axis zoomed to the adjustment, the branch it followed
  highlighted with its steps and the optimum it stopped at; beside it, for context, ``y*``
  on the branches through the final grasp over a wider range of ``q1``.
* :func:`write_gif`: every step of the plan, captioned.

The images need the ``viz`` extra (matplotlib, imageio).
"""

from __future__ import annotations

import itertools
import math
import textwrap
from collections import Counter
from pathlib import Path

import numpy as np

from grasp_env import planning
from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.simulator import Simulator

#: Frames of the filmstrip (the paper's Fig. 13 has 15) and its layout.
FILMSTRIP_FRAMES = 15
FILMSTRIP_COLUMNS = 5
FRAME_SIZE = (320, 240)
#: Font size (pixels) of the filmstrip's frame titles and legend; lines of text are about
#: 17 pixels high from the top of a digit to the bottom of a "g".
TITLE_FONT = 24
GIF_SIZE = (480, 360)
GIF_FONT = 22
GIF_FRAME_MS = 120
#: Half-width (rad) of the finger-1 range of the context panel of the Fig. 14 plot about
#: the final grasp.
BRANCH_HALF_WIDTH = 0.15
#: Samples of each branch curve traced across the zoomed panel of the Fig. 14 plot.
BRANCH_SAMPLES = 161


# ---------------------------------------------------------------------- events and frames
def _status(plan: planning.Plan) -> str:
    return "form closure" if plan.success else plan.status.replace("_", " ")


def _contact_name(body: str, kind: str) -> str:
    name = body.replace("finger", "finger ")
    return f"{name} tip" if kind == "tip" else name


def plan_events(plan: planning.Plan) -> dict[int, str]:
    """What happens at each notable step of the plan, as a short label by step index.

    The start, the last pre-liftoff step (fingers closed), contact changes (a new contact, a
    contact breaking, one turning into another), the object tipping (a support contact
    breaking) and lifting off, a constrained fall, via points, form closure, the start of
    grip adjustment and the final grasp.
    """
    steps = plan.steps
    if not steps:
        return {}
    events: dict[int, str] = {0: "start"}
    bounds = plan.phase_bounds()
    if "pre-liftoff" in bounds and bounds["pre-liftoff"][1] > 0:
        events[bounds["pre-liftoff"][1]] = "fingers closed"
    for i in range(1, len(steps)):
        prev, st = steps[i - 1].state, steps[i].state
        before = Counter((c.body, c.kind) for c in prev.contacts)
        after = Counter((c.body, c.kind) for c in st.contacts)
        added = sorted((after - before).elements())
        removed = sorted((before - after).elements())
        label = ""
        if "fall_start" in steps[i].note:
            label = "constrained fall"
        elif prev.on_support and not st.on_support:
            label = "lift-off"
            if added:
                label += f"; {_contact_name(*added[0])} touches"
        elif steps[i].note.startswith("via"):
            label = "via point"
        elif added and removed and added[0][0] == removed[0][0]:
            label = f"{_contact_name(added[0][0], '')}: {removed[0][1]} -> {added[0][1]} contact"
        elif added and removed:
            label = f"{_contact_name(*removed[0])} off, {_contact_name(*added[0])} on"
        elif added:
            label = f"{_contact_name(*added[0])} touches"
        elif removed == [("support", "edge")] or (removed and removed[0][0] == "support"):
            label = "tips: support contact breaks"
        elif removed:
            label = f"{_contact_name(*removed[0])} lets go"
        if label:
            events[i] = label
    fc = plan.form_closure_step()
    if fc is not None:
        touch = events.get(fc, "")
        events[fc] = "form closure" + (f" ({touch})" if touch.endswith("touches") else "")
    if "grip adjustment" in bounds:
        events.setdefault(bounds["grip adjustment"][0], "grip adjustment starts")
    last = len(steps) - 1
    if last > 0:
        events[last] = "final grasp" if plan.success else f"end ({_status(plan)})"
    return events


def _motion(plan: planning.Plan) -> np.ndarray:
    """Cumulative motion of the bodies along the plan (palm widths): per step, the largest
    displacement of any vertex of the palm, the fingers or the object."""
    pts = []
    for st in plan.steps:
        s = st.state
        obj = geo.transform(s.object_pose, s.scene.object.vertices_B)
        pts.append(np.vstack([*kin.hand_polygons_W(s.scene, s.hand), obj]))
    w = plan.steps[0].state.scene.palm.width
    d = [0.0] + [float(np.linalg.norm(b - a, axis=1).max()) / w for a, b in itertools.pairwise(pts)]
    return np.cumsum(d)


#: Which events the filmstrip keeps first when there are more than it has frames.
_EVENT_PRIORITY = ("final grasp", "start", "form closure", "lift-off", "grip adjustment starts")


def frame_indices(plan: planning.Plan, n: int) -> list[int]:
    """``n`` step indices (all steps if there are fewer) for the filmstrip: the steps of
    :func:`plan_events` first (by ``_EVENT_PRIORITY``, then in order), then, while frames are
    left, the step halfway (in motion of the bodies) through the stretch between chosen
    frames in which the bodies move most; stretches where nothing moves get no frames."""
    last = len(plan.steps) - 1
    if last < 0:
        return []
    events = plan_events(plan)

    def rank(i: int) -> tuple[int, int]:
        label = events[i]
        for k, key in enumerate(_EVENT_PRIORITY):
            if label.startswith(key):
                return (k, i)
        return (len(_EVENT_PRIORITY), i)

    keep = set(sorted(events, key=rank)[:n])
    s = _motion(plan)
    while len(keep) < min(n, last + 1):
        chosen = sorted(keep)
        gaps = [(s[b] - s[a], a, b) for a, b in itertools.pairwise(chosen) if b - a > 1]
        if not gaps:
            break
        moved, a, b = max(gaps)
        if moved <= 1e-9:  # nothing moves between any two frames: spread them evenly
            _, a, b = max((b - a, a, b) for _, a, b in gaps)
            keep.add((a + b) // 2)
            continue
        inner = np.arange(a + 1, b)
        keep.add(int(inner[np.argmin(np.abs(s[inner] - 0.5 * (s[a] + s[b])))]))
    return sorted(keep)


def _caption(
    plan: planning.Plan, i: int, weight: float, events: dict[int, str] | None = None
) -> str:
    """One line: step, phase, event (``events``: :func:`plan_events`) and ``y*``."""
    st = plan.steps[i]
    text = f"{i}: {st.phase}"
    event = (plan_events(plan) if events is None else events).get(i)
    if event:
        text += f" - {event}"
    if math.isfinite(st.grip):
        text += f", y* = {st.grip / weight:.4f} W"
    return text


def _title(plan: planning.Plan, i: int, events: dict[int, str], weight: float) -> list[str]:
    """Two lines: the step and what happens there; the phase and ``y*``."""
    st = plan.steps[i]
    first = f"step {i}" + (f": {events[i]}" if i in events else "")
    second = st.phase
    if math.isfinite(st.grip):
        second += f", y* = {st.grip / weight:.4f} W"
    return [first, second]


def plan_bounds(plan: planning.Plan, margin: float = 0.05) -> tuple[float, float, float, float]:
    """World box ``(x_min, x_max, y_min, y_max)`` around every hand and object of the plan, plus
    ``margin`` palm widths, and the support band below ``y = 0``."""
    pts = []
    for st in plan.steps:
        s = st.state
        pts.append(geo.transform(s.object_pose, s.scene.object.vertices_B))
        pts.extend(kin.hand_polygons_W(s.scene, s.hand))
    p = np.vstack(pts)
    m = margin * plan.steps[0].state.scene.palm.width
    return (p[:, 0].min() - m, p[:, 0].max() + m, -m, p[:, 1].max() + m)


# ---------------------------------------------------------------------- images
def write_filmstrip(plan: planning.Plan, path: Path) -> list[int]:
    """Frames of the plan in a grid (like the paper's Fig. 13), each titled with its step and
    event, its phase and ``y*``, above a legend; returns the steps shown."""
    from grasp_env.render import Renderer

    idx = frame_indices(plan, FILMSTRIP_FRAMES)
    events = plan_events(plan)
    scene = plan.steps[0].state.scene
    weight = scene.object_weight
    w, h = FRAME_SIZE
    cols = min(FILMSTRIP_COLUMNS, len(idx))
    rows = math.ceil(len(idx) / cols)
    gap = 6
    sheet_w = cols * w + (cols + 1) * gap
    renderer = Renderer(w, h, world_bounds=plan_bounds(plan), font_size=TITLE_FONT, text_band=False)
    try:
        cells = []
        for i in idx:
            frame = renderer.draw(plan.steps[i].state)
            title = renderer.text_image(_title(plan, i, events, weight), w, bold_first=True)
            cells.append(np.vstack([title, frame]))
        n_steps = len(plan.steps)
        heading = renderer.text_image(
            [f"{scene.name}: {len(idx)} of the plan's {n_steps} steps ({_status(plan)})"],
            sheet_w,
            bold_first=True,
        )
        legend = renderer.legend(sheet_w)
    finally:
        renderer.close()
    ch = cells[0].shape[0]
    grid = np.full((rows * (ch + gap), sheet_w, 3), 255, np.uint8)
    for k, cell in enumerate(cells):
        r, c = divmod(k, cols)
        y0, x0 = r * (ch + gap), gap + c * (w + gap)
        grid[y0 : y0 + ch, x0 : x0 + w] = cell
        # a thin frame around the drawing
        grid[y0 + ch - h - 1, x0 : x0 + w] = 200
        grid[y0 + ch - 1, x0 : x0 + w] = 200
        grid[y0 + ch - h - 1 : y0 + ch, x0] = 200
        grid[y0 + ch - h - 1 : y0 + ch, x0 + w - 1] = 200
    sheet = np.vstack([heading, grid, legend])
    _save_png(sheet, path)
    return idx


def _save_png(image: np.ndarray, path: Path) -> None:
    imageio = _viz("imageio.v2")
    imageio.imwrite(path, image)


def write_gif(plan: planning.Plan, path: Path) -> None:
    """Animated GIF of every step of the plan, each frame captioned (step, phase, event,
    ``y*``) above the legend."""
    from grasp_env.render import Renderer

    imageio = _viz("imageio.v2")
    weight = plan.steps[0].state.scene.object_weight
    events = plan_events(plan)
    renderer = Renderer(*GIF_SIZE, world_bounds=plan_bounds(plan), font_size=GIF_FONT)
    try:
        legend = renderer.legend()
        frames = [
            np.vstack([renderer.draw(st.state, _caption(plan, i, weight, events)), legend])
            for i, st in enumerate(plan.steps)
        ]
    finally:
        renderer.close()
    imageio.mimsave(path, frames, duration=GIF_FRAME_MS, loop=0)


# ---------------------------------------------------------------------- Fig. 14
def _branch_key(plan: planning.Plan, probe: planning.BranchProbe) -> tuple:
    contacts = plan.steps[probe.step].state.contacts
    return tuple(sorted(contacts[k].key for k in probe.kept))


def _branch_label(plan: planning.Plan, probe: planning.BranchProbe) -> str:
    """The contacts a branch keeps (numbered as in the state it was evaluated from) and the
    ones it breaks."""
    contacts = plan.steps[probe.step].state.contacts
    kept = ", ".join(
        f"{k + 1} {_contact_name(contacts[k].body, contacts[k].kind)}" for k in probe.kept
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
    plt = _viz("matplotlib.pyplot")
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


def _viz(module: str):
    """Import an optional plotting module, with a clear error if the extra is missing."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise SystemExit(
            f"error: {module.split('.')[0]} is needed for the images; "
            "install the viz extra: pip install 'grasp_env[viz]'"
        ) from exc


__all__ = [
    "frame_indices",
    "plan_bounds",
    "plan_events",
    "trace_branch",
    "write_branch_plot",
    "write_filmstrip",
    "write_gif",
]
