"""Figures of a grasp plan: the filmstrip (like the paper's Fig. 13) and an animated GIF;
used by ``python -m agents.scripted``, which also draws the grip adjustment's branch plot
(like Fig. 14, :mod:`agents.grip_branches`).

* :func:`write_filmstrip`: frames at the steps where something happens (the start, the
  tipping, lift-off, contact changes, a constrained fall, form closure, the start of grip
  adjustment, the final grasp; :func:`plan_events`), the rest of the frames where the bodies
  move most (:func:`frame_indices`), each under a two-line title (step and event; phase and
  ``y*``), with a legend of the drawing's colours and marks below.
* :func:`write_gif`: every step of the plan, captioned.

The images need the ``viz`` extra (matplotlib, imageio).
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from pathlib import Path

import numpy as np

from grasp_env import planning
from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin

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


# ---------------------------------------------------------------------- events and frames
def _status(plan: planning.Plan) -> str:
    return "form closure" if plan.success else plan.status.replace("_", " ")


def contact_name(body: str, kind: str) -> str:
    """A contact's body as the figures name it (``finger 1``, ``finger 2 tip``, ...)."""
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
                label += f"; {contact_name(*added[0])} touches"
        elif steps[i].note.startswith("via"):
            label = "via point"
        elif added and removed and added[0][0] == removed[0][0]:
            label = f"{contact_name(added[0][0], '')}: {removed[0][1]} -> {added[0][1]} contact"
        elif added and removed:
            label = f"{contact_name(*removed[0])} off, {contact_name(*added[0])} on"
        elif added:
            label = f"{contact_name(*added[0])} touches"
        elif removed == [("support", "edge")] or (removed and removed[0][0] == "support"):
            label = "tips: support contact breaks"
        elif removed:
            label = f"{contact_name(*removed[0])} lets go"
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


def _title(
    plan: planning.Plan, i: int, events: dict[int, str], weight: float,
    friction: dict[int, float],
) -> list[str]:  # fmt: skip
    """Two lines: the step and what happens there; the phase, ``y*`` and the critical
    friction of the lifting motion it starts (``friction``, by step)."""
    st = plan.steps[i]
    first = f"step {i}" + (f": {events[i]}" if i in events else "")
    second = st.phase
    if math.isfinite(st.grip):
        second += f", y* = {st.grip / weight:.4f} W"
    if i in friction:
        second += f", mu* = {friction[i]:.3g}"
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
def write_filmstrip(
    plan: planning.Plan, path: Path, friction: dict[int, float] | None = None
) -> list[int]:
    """Frames of the plan in a grid (like the paper's Fig. 13), each titled with its step and
    event, its phase, ``y*`` and, where given by step (``friction``), the critical friction
    of the lifting motion it starts; above a legend; returns the steps shown."""
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
            title = renderer.text_image(
                _title(plan, i, events, weight, friction or {}), w, bold_first=True
            )
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
    imageio = viz("imageio.v2")
    imageio.imwrite(path, image)


def write_gif(plan: planning.Plan, path: Path) -> None:
    """Animated GIF of every step of the plan, each frame captioned (step, phase, event,
    ``y*``) above the legend."""
    from grasp_env.render import Renderer

    imageio = viz("imageio.v2")
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


def viz(module: str):
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
    "write_filmstrip",
    "write_gif",
]
