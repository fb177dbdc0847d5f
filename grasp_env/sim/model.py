"""The scene as the compiled simulator sees it: plain arrays and numbers, built once per
:class:`~grasp_env.simulator.Simulator`.

A :class:`Model` is a named tuple, so every compiled function takes it as one argument and
reads its fields by name, compiled or interpreted (``NUMBA_DISABLE_JIT=1``).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE

#: Fields of :class:`Model`, with what they hold.
FIELDS = {
    "points": "stacked body-frame vertices then edge normals (grasp_env.sim.placement)",
    "body": "body of each row of points (0 object, 1 palm, 2 finger 1, 3 finger 2)",
    "n_object": "object vertices",
    "n_vertices": "object and hand vertices (rows of points before the normals)",
    "half": "half the palm width (the joints' offset from the palm frame)",
    "tol": "contact tolerance, in length units",
    "newton_tol": "gap below which Newton stops",
    "ftol": "force tolerance of the equilibrium tests",
    "size": "largest distance of an object vertex from the centre of mass",
    "rho": "the object's radius of gyration",
    "weight": "the object's weight W",
    "length": "the palm width: the unit of the moments in the equilibrium rows",
    "scale": "(1, 1, 1/rho): a twist as a scaled twist",
    "per_length": "(1, 1, 1/length): wrench rows with moments per palm width",
    "gravity": "the wrench (0, W, 0) the contacts must supply",
    "max_step": "largest increment of the path parameter between checks",
    "fall_step": "largest object displacement of one fall step",
    "max_iterations": "cap on increments per move (and on steps per fall)",
    "max_solves": "cap on pose solves per call",
    "reach": "largest distance of each hand body's vertices from its frame origin (3,)",
    "thinnest": "the thinnest of object, palm and fingers",
    "reference_lp": "solve the motion LP with HiGHS (the reference path) instead of the "
    "exact basis enumeration",
    "python_lp": "whether compiled code may call HiGHS (through Python) for a motion LP the "
    "basis enumeration cannot decide; else it raises SolverError (code that catches errors "
    "in compiled code cannot catch them from Python)",
}

Model = namedtuple("Model", list(FIELDS))
Model.__doc__ = "The compiled simulator's view of one scene; see :data:`FIELDS`."


#: The fields that travel as one float array when a Model crosses from Python into compiled
#: code (:func:`pack`): checking a named tuple's 22 fields' types costs more than the move
#: it carries when the hand touches nothing; arrays cross at once.
ARRAYS = ("points", "body", "scale", "per_length", "gravity", "reach")
NUMBERS = tuple(name for name in FIELDS if name not in ARRAYS)


def pack(model: Model) -> tuple:
    """``model`` as its arrays and one float array of its numbers (:func:`unpack`)."""
    numbers = np.array([float(getattr(model, name)) for name in NUMBERS])
    return (*(getattr(model, name) for name in ARRAYS), numbers)


@njit(cache=CACHE)
def unpack(points, body, scale, per_length, gravity, reach, numbers: np.ndarray) -> Model:
    """The :class:`Model` :func:`pack` made (fields in :data:`FIELDS` order)."""
    n_object, n_vertices, half, tol, newton_tol, ftol, size, rho, weight, length = numbers[:10]
    max_step, fall_step, max_iterations, max_solves, thinnest, reference_lp, python_lp = numbers[
        10:
    ]
    return Model(
        points, body, int(n_object), int(n_vertices), half, tol, newton_tol, ftol, size, rho,
        weight, length, scale, per_length, gravity, max_step, fall_step, int(max_iterations),
        int(max_solves), reach, thinnest, reference_lp != 0.0, python_lp != 0.0,
    )  # fmt: skip
