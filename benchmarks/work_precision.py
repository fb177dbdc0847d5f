"""Work-precision of the simulator: error against a tight reference vs wall time.

Cases:

* ``fig13`` closing motion: the palm stays fixed and both fingers close at equal angular
  rates (the paper's section 4) in moves of ``DQ`` radians until the hand jams; the error is
  the final object pose's.
* seeded random hand paths on bundled scenes: from the pre-liftoff hand set-up, a fixed
  list of absolute hand targets (fingers closing by up to 0.12 rad per move, the palm
  wandering by up to 0.01 palm widths and 0.03 rad); the error is the largest over the
  object poses after each move.

Each case runs for each LP path (``lp_solver="fast"`` and ``"highs"``) over a grid of
``contact_tol`` and ``max_step``; the reference is the HiGHS path at ``contact_tol=1e-11``
(the smallest the simulator takes) and a small ``max_step``, cross-checked by the same at
``1e-10``. Times are medians of ``repeat`` runs.

Usage: ``python -m benchmarks.work_precision [--quick]``
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

import grasp_env
from benchmarks.common import (
    BudgetExceeded,
    median_time,
    page_main,
    table,
    time_limit,
    write,
)
from grasp_env.planning import centred_hand

DQ = 0.01  #: finger increment of the closing motion (rad per move)
SOLVERS = ("fast", "highs")
TARGET_ERROR, TARGET_MS = 1e-9, 5.0  #: target: fig13 closing to this error within this time
REF_TOLS = (1e-11, 1e-10)  #: contact_tol of the reference and of its cross-check
RUN_LIMIT = 60.0  #: seconds after which one run is abandoned ("timeout")


@dataclass(frozen=True)
class Case:
    """A scene and absolute hand targets ``(k, 5)``, or ``None``: the closing motion by ``dq``."""

    name: str
    scene: str
    targets: np.ndarray | None = None
    dq: float = DQ


def closing_motion(sim: grasp_env.Simulator, dq: float = DQ, max_moves: int = 1000):
    """Close both fingers at equal rates until a jam; return the final state and move count."""
    state = sim.reset()
    q1, q2 = state.finger_angles
    for i in range(1, max_moves + 1):
        state = sim.move_hand(state, fingers=(q1 + dq * i, q2 - dq * i))
        if state.jammed:
            return state, i
    return state, max_moves


def random_path(scene: str, seed: int, moves: int) -> Case:
    """A seeded random hand path from the pre-liftoff set-up, as absolute targets."""
    rng = np.random.default_rng(seed)
    sc = grasp_env.load_scene(scene)
    w = sc.palm.width
    steps = np.column_stack(
        [
            rng.uniform(-0.01, 0.01, (moves, 2)) * w,
            rng.uniform(-0.03, 0.03, moves),
            rng.uniform(0.0, 0.12, moves),
            -rng.uniform(0.0, 0.12, moves),
        ]
    )
    return Case(f"{scene} path (seed {seed})", scene, centred_hand(sc) + np.cumsum(steps, axis=0))


@functools.cache
def scene_of(name: str) -> grasp_env.Scene:
    """A bundled scene, read from its file once per process (parsing is not simulation)."""
    return grasp_env.load_scene(name)


def simulate(case: Case, **sim_kwargs) -> tuple[np.ndarray, int, int]:
    """Run a case: the object poses ``(k, 3)`` it is judged on, the moves and the events."""
    sim = grasp_env.Simulator(scene_of(case.scene), **sim_kwargs)
    if case.targets is None:
        state, moves = closing_motion(sim, case.dq)
        return state.object_pose[None, :], moves, len(state.events)
    state = sim.settle(sim.scene.object.start_pose, centred_hand(sim.scene))
    poses, events = [], len(state.events)
    for target in case.targets:
        state = sim.move_hand(state, palm=target[:3], fingers=target[3:])
        poses.append(state.object_pose)
        events += len(state.events)
    return np.array(poses), len(case.targets), events


class Row(NamedTuple):
    """One grid point: errors against the reference and the cross-check, median seconds."""

    solver: str
    tol: float
    max_step: float
    error: float
    error_check: float
    seconds: float
    moves: int
    events: int


def measure(case: Case, grid, ref_step: float, repeat: int) -> tuple[list[Row], list[str]]:
    """The grid's rows and lines describing the reference and the cross-check reference."""
    refs, notes = [], []
    for tol in REF_TOLS:
        t, (poses, moves, events) = median_time(
            lambda c=tol: simulate(case, lp_solver="highs", contact_tol=c, max_step=ref_step), 1
        )
        refs.append(poses)
        notes.append(
            f"contact_tol={tol:.0e}, max_step={ref_step}: {moves} moves, {events} events, "
            f"{t * 1e3:.0f} ms"
        )
    gap = float(np.abs(refs[0] - refs[1]).max())
    notes.append(f"reference vs cross-check: {gap:.2e}" + (" (**disagree**)" if gap > 1e-9 else ""))
    rows = []
    for solver, (tol, max_step) in itertools.product(SOLVERS, grid):
        try:
            with time_limit(RUN_LIMIT * repeat):
                t, (poses, moves, events) = median_time(
                    lambda s=solver, c=tol, m=max_step: simulate(
                        case, lp_solver=s, contact_tol=c, max_step=m
                    ),
                    repeat,
                )
            errs = [float(np.abs(poses - ref).max()) for ref in refs]
        except BudgetExceeded:
            t, errs, moves, events = np.inf, [np.nan, np.nan], 0, 0
        rows.append(Row(solver, tol, max_step, *errs, t, moves, events))
        print(
            f"{case.name}: {solver} tol={tol:.0e} max_step={max_step} err={errs[0]:.2e} "
            f"time={t * 1e3:.1f} ms"
        )
    return rows, notes


def fastest_within(rows: list[Row], solver: str, error: float, check: bool = False) -> Row | None:
    """The fastest row of ``solver`` within ``error`` of the reference (or of the cross-check
    reference), None if there is none."""
    ok = [r for r in rows if r.solver == solver and (r.error_check if check else r.error) <= error]
    return min(ok, key=lambda r: r.seconds) if ok else None


def _target_line(rows: list[Row], solver: str, check: bool) -> str:
    best = fastest_within(rows, solver, TARGET_ERROR, check)
    ref = f"contact_tol={REF_TOLS[check]:.0e} reference"
    if best is None:
        return f"* `{solver}` vs the {ref}: no setting reached the error"
    met = "met" if best.seconds * 1e3 <= TARGET_MS else "not met"
    return (
        f"* `{solver}` vs the {ref}: {best.seconds * 1e3:.1f} ms (contact_tol={best.tol:.0e}, "
        f"max_step={best.max_step}); target <= {TARGET_MS:g} ms: {met}"
    )


def run(
    quick: bool,
    out: Path,
    paths: int = 5,
    moves: int = 12,
    repeat: int = 3,
    dq: float = DQ,
    fig13: bool = True,
) -> Path:
    """Run the work-precision benchmark (``fig13=False``: the random paths only) and write its
    markdown page."""
    if quick:
        paths, moves, repeat = min(paths, 1), min(moves, 4), 1
        fig13_grid = [(1e-7, 1.0), (1e-9, 1.0)]
        path_grid = [(1e-9, 1.0)]
        fig13_ref = path_ref = 0.25
    else:
        fig13_grid = list(itertools.product((1e-5, 1e-7, 1e-9), (1.0, 0.25, 0.05)))
        path_grid = list(itertools.product((1e-5, 1e-7, 1e-9), (1.0, 0.25)))
        fig13_ref, path_ref = 0.01, 0.05
    scenes = [s for s in grasp_env.bundled_scenes() if s != "fig13"]
    closing = Case(f"fig13 closing motion ({dq:g} rad per move)", "fig13", dq=dq)
    cases = [(closing, fig13_grid, fig13_ref, repeat)] if fig13 else []
    cases += [
        (random_path(scenes[i % len(scenes)], i, moves), path_grid, path_ref, 1)
        for i in range(paths)
    ]
    body = [
        "Error: max |object pose - reference| (x, y in scene units, angle in rad). Reference: "
        f'`lp_solver="highs"`, `contact_tol={REF_TOLS[0]:.0e}`, a small `max_step`; the '
        f"cross-check reference is the same at `contact_tol={REF_TOLS[1]:.0e}` (where the two "
        "disagree the reference itself is not converged). Times: median of "
        f"{repeat} runs for fig13, one run for the paths (whole motion, new Simulator each, "
        "on a scene read from its file once).",
        "",
    ]
    summary = []
    for case, grid, ref_step, rep in cases:
        rows, notes = measure(case, grid, ref_step, rep)
        body += [
            f"## {case.name}",
            "",
            "Reference: " + "; cross-check: ".join(notes[:2]) + "; " + notes[2] + ".",
            "",
            *table(
                [
                    "lp_solver",
                    "contact_tol",
                    "max_step",
                    "pose error",
                    "error vs cross-check",
                    "time (ms)",
                    "moves",
                    "events",
                ],
                [
                    (
                        r.solver,
                        f"{r.tol:.0e}",
                        r.max_step,
                        f"{r.error:.2e}",
                        f"{r.error_check:.2e}",
                        f"{r.seconds * 1e3:.1f}",
                        r.moves,
                        r.events,
                    )
                    for r in rows
                ],
                "llrrrrrr",
            ),
            "",
        ]
        if case.targets is None:
            summary += [_target_line(rows, s, c) for s in SOLVERS for c in (False, True)]
    head = (
        [f"## fig13 closing motion to error <= {TARGET_ERROR:g}", "", *summary, ""] if fig13 else []
    )
    return write(out, "Work-precision of the simulator", body[:2] + head + body[2:])


def main(argv: list[str] | None = None) -> int:
    return page_main(argv, run, "work_precision.md", "a small grid (about 15 s)")


if __name__ == "__main__":
    raise SystemExit(main())
