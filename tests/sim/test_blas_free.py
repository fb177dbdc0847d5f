"""The simulator's modules make no BLAS or LAPACK call, so that a step gives the same bits
on every machine: numpy's ``@``, ``dot``, ``einsum``, ``linalg`` and scipy go through the
machine's BLAS, whose kernels round differently from one processor (or
``OPENBLAS_CORETYPE``) to another. Small products are written out, and factorizations come
from :mod:`grasp_env.solvers.dense`."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "grasp_env"
#: Modules on the path of an env step (the analysis LPs go through scipy's HiGHS, in
#: solvers/lp.py, which needs no BLAS).
SIMULATION = [
    "simulator.py",
    "arguments.py",
    "core/geometry.py",
    "core/kinematics.py",
    "core/scene.py",
    "core/state.py",
    "mechanics/closure.py",
    "mechanics/contacts.py",
    "mechanics/width.py",
    "envs/shapes.py",
    *(
        str(p.relative_to(PACKAGE))
        for package in ("solvers", "sim")
        for p in sorted((PACKAGE / package).glob("*.py"))
        if p.name != "lp.py"
    ),
]
BLAS_NAMES = {"dot", "vdot", "inner", "matmul", "tensordot", "einsum", "linalg"}


def blas_uses(source: str) -> list[str]:
    """Lines that multiply matrices with ``@``, call ``x.dot`` or ``np.<blas name>`` (not
    ``dense.<name>``), or import scipy."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.BinOp | ast.AugAssign) and isinstance(node.op, ast.MatMult):
            found.append(f"line {node.lineno}: @")
        elif (
            isinstance(node, ast.Attribute)
            and node.attr in BLAS_NAMES
            and not (isinstance(node.value, ast.Name) and node.value.id == "dense")
        ):
            found.append(f"line {node.lineno}: .{node.attr}")
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
            if any(n.split(".")[0] == "scipy" for n in names):
                found.append(f"line {node.lineno}: scipy import")
    return found


@pytest.mark.parametrize("module", SIMULATION)
def test_simulation_modules_call_no_blas(module: str) -> None:
    assert blas_uses((PACKAGE / module).read_text()) == []


def test_the_check_sees_blas_calls() -> None:
    src = "\n".join(
        [
            "import numpy as np",
            "from scipy.optimize import nnls",
            "a = b @ c",
            "x = np.linalg.solve(A, b)",
            "y = u.dot(v) + dense.dot(u, v)",
        ]
    )
    assert len(blas_uses(src)) == 4


RUN = """
import numpy as np, grasp_env
sim = grasp_env.Simulator("fig13")
state = sim.reset()
q1, q2 = state.finger_angles
state = sim.move_hand(state, fingers=(q1 + 0.8, q2 - 0.8))
state = sim.move_hand(state, palm=state.hand[:3] + np.array([0.02, 0.05, 0.05]))
forces = np.array([c.force for c in state.contacts])
print(state.object_pose.tobytes().hex(), forces.tobytes().hex(), grasp_env.grip_objective(state))
"""


def run_in(env: dict[str, str | None]) -> str:
    """The bits of a closing and lifting motion's end state, computed in a fresh process
    with the given environment changes (None unsets)."""
    full = dict(os.environ)
    for key, value in env.items():
        if value is None:
            full.pop(key, None)
        else:
            full[key] = value
    out = subprocess.run([sys.executable, "-c", RUN], env=full, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_openblas_core_types_change_no_bit() -> None:
    """The oldest kernels OpenBLAS has (Prescott: no FMA, no AVX) and Haswell's give the
    same bits as the machine's own."""
    unset = {"OPENBLAS_CORETYPE": None, "OPENBLAS_L2_SIZE": None}
    own = run_in(unset)
    assert run_in({"OPENBLAS_CORETYPE": "Prescott"}) == own
    assert run_in({"OPENBLAS_CORETYPE": "Haswell", "OPENBLAS_L2_SIZE": "512"}) == own


def test_interpreted_kernels_give_the_same_bits() -> None:
    """The compiled kernels and the same source run as Python (``NUMBA_DISABLE_JIT=1``, how
    to debug them) compute the same bits: no fused multiply-adds, the same order."""
    assert run_in({"NUMBA_DISABLE_JIT": "1"}) == run_in({"NUMBA_DISABLE_JIT": None})
