"""Work-precision table of the simulator on the paper's fig13 closing motion.

The palm stays fixed and both fingers close at equal angular rates (the paper's section 4)
in moves of ``--dq`` radians until the hand jams. For each ``contact_tol`` and ``max_step`` the
final object pose is compared with a reference run at the tightest settings, and the wall
time of the whole closing motion is recorded (best of ``--repeat``).

Usage: ``python benchmarks/work_precision.py [--out benchmarks/results/work_precision.md]``
"""

from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

import numpy as np

import grasp_env


def closing_motion(sim: grasp_env.Simulator, dq: float, max_moves: int = 1000):
    """Close both fingers at equal rates until a jam; return the final state and move count."""
    state = sim.reset()
    q1, q2 = state.finger_angles
    for i in range(1, max_moves + 1):
        state = sim.move_hand(state, fingers=(q1 + dq * i, q2 - dq * i))
        if state.jammed:
            return state, i
    return state, max_moves


def run(scene: str, tol: float, max_step: float, dq: float, repeat: int):
    best, state = np.inf, None
    for _ in range(repeat):
        sim = grasp_env.Simulator(scene, contact_tol=tol, max_step=max_step)
        t0 = time.perf_counter()
        state, moves = closing_motion(sim, dq)
        best = min(best, time.perf_counter() - t0)
    return state, moves, best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="fig13")
    ap.add_argument("--dq", type=float, default=0.01, help="finger increment per move (rad)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "work_precision.md"
    )
    args = ap.parse_args(argv)

    ref, ref_moves, ref_time = run(args.scene, 1e-12, 0.01, args.dq, 1)
    rows = []
    for tol in (1e-5, 1e-7, 1e-9, 1e-11):
        for max_step in (1.0, 0.25, 0.05):
            state, moves, t = run(args.scene, tol, max_step, args.dq, args.repeat)
            err = float(np.abs(state.object_pose - ref.object_pose).max())
            rows.append(
                (tol, max_step, err, t, moves, state.jammed, grasp_env.is_form_closure(state))
            )
            print(f"tol={tol:.0e} max_step={max_step:<5} error={err:.2e} time={t * 1e3:8.1f} ms")
    lines = [
        f"# Work-precision: `{args.scene}` closing motion "
        f"(fingers at equal rates, {args.dq} rad/move)",
        "",
        f"Machine: {platform.machine()}, {platform.processor() or 'cpu'}, Python "
        f"{platform.python_version()}, numpy {np.__version__}, {time.strftime('%Y-%m-%d')}.",
        f"Reference: contact_tol=1e-12, max_step=0.01 ({ref_moves} moves, "
        f"{ref_time * 1e3:.0f} ms); "
        "error = max |object pose - reference| at the jam.",
        "",
        "| contact_tol | max_step | pose error | time (ms) | moves | jammed | form closure |",
        "| ---: | ---: | ---: | ---: | ---: | :---: | :---: |",
    ]
    for tol, ms, err, t, moves, jam, fc in rows:
        lines.append(f"| {tol:.0e} | {ms} | {err:.2e} | {t * 1e3:.1f} | {moves} | {jam} | {fc} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
