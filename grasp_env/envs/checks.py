"""Checks of ``FrictionlessGrasp-v0``'s constructor arguments and reset options: errors name
the argument and show the value."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from grasp_env.arguments import number, short
from grasp_env.core import kinematics as kin
from grasp_env.core.scene import LENGTH_RANGE, Scene
from grasp_env.envs.shapes import DEFAULT_SHAPE_RANGES
from grasp_env.kernel.observation import PALM_THETA_MAX, PALM_X_RANGE, PALM_Y_MAX

#: Largest aspect ratio of the shape randomizer: a 1:100 shape is already a thin plate.
MAX_ASPECT = 100.0


def placement_problem(
    scene: Scene, object_pose: np.ndarray, hand: np.ndarray, contact_tol: float
) -> str | None:
    """Why a hand configuration is not allowed with the object at ``object_pose`` (None if
    it is), at the simulator's contact tolerance ``contact_tol`` (relative to the palm width),
    as the simulator's ``settle`` checks it."""
    return kin.hand_placement_problem(scene, object_pose, hand, contact_tol * scene.palm.width)


def palm_problem(scene: Scene, palm: np.ndarray) -> str | None:
    """Why a palm pose lies outside the env's palm workspace (None if it is inside)."""
    x, y, th = (float(v) for v in palm)
    w, x0 = scene.palm.width, float(scene.object.start_pose[0])
    if abs(x - x0) > PALM_X_RANGE * w or not 0 <= y <= PALM_Y_MAX * w:
        return (
            f"{[x, y, th]} is outside the palm workspace |x - x0| <= {PALM_X_RANGE * w:.6g}, "
            f"0 <= y <= {PALM_Y_MAX * w:.6g} (x0 = {x0!r}, the object's x at its scene "
            f"placement: |x - x0| = {abs(x - x0)!r})"
        )
    if abs(th) > PALM_THETA_MAX:
        return f"angle {th!r} is outside [-pi/2, pi/2]"
    return None


def spec_name(spec: Any) -> str:
    """A scene spec for an error message: a Scene by its name, anything else shortened."""
    return repr(spec.name) if isinstance(spec, Scene) else short(spec)


def flag(value: Any, name: str) -> bool:
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be a bool, got {value!r}")
    return bool(value)


def one_of(value: Any, name: str, choices, also: str = "") -> Any:
    """``value`` if it is one of ``choices``, else ``ValueError`` listing them (``also``
    names what else is allowed)."""
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"{name} must be {also}one of {list(choices)}, got {value!r}")
    return value


def numbers(value: Any, name: str, size: int, lo: float, hi: float) -> np.ndarray:
    if not isinstance(value, list | tuple | np.ndarray) or len(value) != size:
        raise ValueError(f"{name} must be {size} numbers, got {value!r}")
    return np.array([number(v, f"{name}[{i}]", lo, hi) for i, v in enumerate(value)])


def shape_ranges(value: Any, max_vertices: int) -> dict[str, tuple[float, float]] | None:
    if value is None or value is False:
        return None
    if value is True:
        value = {}
    if not isinstance(value, dict):
        raise TypeError(f"shape_randomizer must be None, True or a dict, got {value!r}")
    unknown = sorted(set(value) - set(DEFAULT_SHAPE_RANGES), key=str)
    if unknown:
        raise ValueError(
            f"shape_randomizer: unknown key(s) {unknown}; allowed: {list(DEFAULT_SHAPE_RANGES)}"
        )
    out = dict(DEFAULT_SHAPE_RANGES)
    for key, raw in value.items():
        name = f"shape_randomizer[{key!r}]"
        if not isinstance(raw, list | tuple) or len(raw) != 2:
            raise ValueError(f"{name} must be a (low, high) pair, got {raw!r}")
        lo, hi = (number(x, name, 0.0, math.inf, hi_open=True) for x in raw)
        if lo > hi:
            raise ValueError(f"{name} must have low <= high, got {raw!r}")
        if key == "vertices":
            if any(isinstance(x, bool) or not isinstance(x, int | np.integer) for x in raw):
                raise TypeError(f"{name} must be two ints, got {raw!r}")
            if lo < 3 or hi > max_vertices:
                raise ValueError(f"{name} must lie in [3, max_vertices={max_vertices}]: {raw!r}")
            lo, hi = int(lo), int(hi)
        if key == "aspect" and not 1.0 <= lo <= hi <= MAX_ASPECT:
            raise ValueError(f"{name} must lie in [1, {MAX_ASPECT:g}], got {raw!r}")
        if key == "size" and not LENGTH_RANGE[0] <= lo <= hi <= LENGTH_RANGE[1]:
            raise ValueError(
                f"{name} must lie in [{LENGTH_RANGE[0]:g}, {LENGTH_RANGE[1]:g}] palm widths "
                f"(the scene's range of object sizes), got {raw!r}"
            )
        out[key] = (lo, hi)
    return out
