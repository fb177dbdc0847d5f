"""The simulator's modules make no BLAS or LAPACK call, so that a step gives the same bits
on every machine: numpy's ``@``, ``dot``, ``einsum``, ``linalg`` and scipy go through the
machine's BLAS, whose kernels round differently from one processor (or
``OPENBLAS_CORETYPE``) to another. Small products are written out, and factorizations come
from :mod:`grasp_env.sim.dense`."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "grasp_env"
#: Modules on the path of an env step (the analysis LPs go through scipy's HiGHS, in lp.py,
#: which needs no BLAS).
SIMULATION = [
    "simulator.py",
    "mechanics.py",
    "contacts.py",
    "fastlp.py",
    "qp.py",
    "geometry.py",
    "kinematics.py",
    "width.py",
    "scene.py",
    "state.py",
    "envs/shapes.py",
    *(str(p.relative_to(PACKAGE)) for p in sorted((PACKAGE / "sim").glob("*.py"))),
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
