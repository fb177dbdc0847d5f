"""Command-line summary of a scene's grasp analysis: ``python -m grasp_env.analyze --scene NAME``.

Prints the object's mass, weight, area and width (section 3.2), its left and right
tippability regions (section 2.4) and the closure status of the scene's initial state
(section 2.5, eqs. 31-36): its contacts, form closure, force closure and the grip objective
``y*``. The scene is a bundled name or a path to a YAML file (docs/conventions.md, "Scene
schema").

Exit status: 0 on success; 2 when the scene cannot be loaded (the message, which names the
field and the value, goes to stderr as ``error: <message>``). A failure of the simulator or
of an analysis function is reported in the output, not raised.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from typing import TextIO

import numpy as np

import grasp_env
from grasp_env.cli import HelpFormatter
from grasp_env.core import geometry as geo
from grasp_env.core.scene import Scene
from grasp_env.core.state import State
from grasp_env.errors import SceneError
from grasp_env.mechanics.tippability import TippabilityRegion


def _num(x: float) -> str:
    """A number in short readable form (``0`` rather than ``-0``)."""
    return f"{x + 0.0:.6g}"


def _point(p: np.ndarray) -> str:
    return f"({_num(float(p[0]))}, {_num(float(p[1]))})"


def format_region(region: TippabilityRegion) -> list[str]:
    """Lines describing one tippability region (paper section 2.4).

    Edge subregions give the edge index, the open interval of the edge parameter ``t`` (0 at
    vertex ``i``, 1 at vertex ``i + 1``) and its world endpoints at the scene placement; vertex
    subregions give the interval of contact-normal angles, CCW from +x, in degrees, with
    ``[``/``]`` for closed and ``(``/``)`` for open ends.
    """
    side = (
        "right (tips clockwise about the right support contact)"
        if region.side == "right"
        else "left (tips counter-clockwise about the left support contact)"
    )
    lines = [f"  {side}, support contact {_point(region.contact_W)}:"]
    if region.is_empty:
        lines.append("    empty")
        return lines
    for e in region.edges:
        lines.append(
            f"    edge {e.edge}: t in ({_num(e.t_start)}, {_num(e.t_end)}), "
            f"from {_point(e.start_W)} to {_point(e.end_W)}"
        )
    for v in region.vertices:
        lo = "[" if v.min_closed else "("
        hi = "]" if v.max_closed else ")"
        lines.append(
            f"    vertex {v.vertex} at {_point(region.vertices_W[v.vertex])}: normal angle in "
            f"{lo}{math.degrees(v.angle_min):.2f}, {math.degrees(v.angle_max):.2f}{hi} deg"
        )
    return lines


def format_contacts(state: State) -> list[str]:
    lines = [f"  contacts ({len(state.contacts)}):"]
    for c in state.contacts:
        lines.append(
            f"    {c.body:<8} {c.kind:<4} point {_point(c.point)} normal {_point(c.normal)} "
            f"force {_num(c.force)}"
        )
    return lines


def _analysis_line(label: str, fn, state: State) -> str:
    try:
        return f"  {label}: {fn(state)}"
    except Exception as exc:  # report, never raise: this is a diagnostic tool
        return f"  {label}: error: {type(exc).__name__}: {exc}"


def report(scene: Scene, out: TextIO) -> None:
    """Write the analysis of ``scene`` to ``out``."""
    obj = scene.object
    area = geo.polygon_area(obj.vertices_B)
    print(f"scene: {scene.name}", file=out)
    if scene.source:
        print(f"source: {scene.source}", file=out)
    print(
        f"object: {len(obj.vertices_B)} vertices, mass {_num(obj.mass)}, "
        f"weight {_num(scene.object_weight)}, area {_num(area)}, "
        f"width {_num(grasp_env.object_width(scene))}",
        file=out,
    )
    print("tippability regions (object at rest on its supporting edge):", file=out)
    try:
        left, right = grasp_env.tippability_regions(scene)
        for region in (left, right):
            for line in format_region(region):
                print(line, file=out)
    except Exception as exc:  # e.g. an object that does not rest on an edge
        print(f"  error: {type(exc).__name__}: {exc}", file=out)

    print("initial state (Simulator(scene).reset()):", file=out)
    try:
        state = grasp_env.Simulator(scene).reset()
    except Exception as exc:
        print(f"  error: the simulator failed: {type(exc).__name__}: {exc}", file=out)
        return
    print(
        f"  object pose: {_point(state.object_pose)} theta {_num(state.object_pose[2])}", file=out
    )
    for line in format_contacts(state):
        print(line, file=out)
    print(_analysis_line("form closure", grasp_env.is_form_closure, state), file=out)
    print(_analysis_line("force closure", grasp_env.is_force_closure, state), file=out)
    print(_analysis_line("grip objective y*", grasp_env.grip_objective, state), file=out)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m grasp_env.analyze`` and ``grasp-analyze``; returns the exit
    status (0 success, 2 bad scene or bad arguments)."""
    parser = argparse.ArgumentParser(
        prog="python -m grasp_env.analyze",
        description="Tippability, width and initial closure status of a grasp scene.",
        epilog=f"bundled scenes: {', '.join(grasp_env.bundled_scenes())}",
        formatter_class=HelpFormatter,
    )
    parser.add_argument(
        "--scene",
        "--scenes",
        dest="scene",
        required=True,
        help="a bundled scene name or a path to a scene YAML file",
    )
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse has printed the usage or the help
        return int(exc.code or 0)
    try:
        scene = grasp_env.load_scene(args.scene)
    except (SceneError, ValueError, TypeError) as exc:
        print(f"error: --scene {args.scene!r}: {exc}", file=sys.stderr)
        return 2
    report(scene, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
