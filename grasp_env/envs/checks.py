"""Checks of what ``FrictionlessGrasp-v0`` and its batched env take in: constructor
arguments, scenes, reset options and actions. Errors name the argument and show the value."""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import Any

import numpy as np

from grasp_env.arguments import number, real_array, real_vector, short
from grasp_env.core import kinematics as kin
from grasp_env.core.scene import LENGTH_RANGE, MAX_ANGLE, Scene
from grasp_env.core.scene_loading import load_scene
from grasp_env.envs.shapes import DEFAULT_SHAPE_RANGES, hand_setup
from grasp_env.envs.uncertainty import MAX_UNCERTAINTY, UNCERTAINTY_KEYS
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
    outside = workspace_problem(scene, x, y)
    if outside:
        return f"{[x, y, th]} {outside}"
    if abs(th) > PALM_THETA_MAX:
        return f"angle {th!r} is outside [-pi/2, pi/2]"
    return None


def workspace_problem(scene: Scene, x: float, y: float) -> str | None:
    """Why a point ``(x, y)`` lies outside the env's palm workspace (None if it is inside)."""
    x, y = float(x), float(y)
    w, x0 = scene.palm.width, float(scene.object.start_pose[0])
    if abs(x - x0) > PALM_X_RANGE * w or not 0 <= y <= PALM_Y_MAX * w:
        return (
            f"is outside the palm workspace |x - x0| <= {PALM_X_RANGE * w:.6g}, "
            f"0 <= y <= {PALM_Y_MAX * w:.6g} (x0 = {x0!r}, the object's x at its scene "
            f"placement: |x - x0| = {abs(x - x0)!r})"
        )
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


class RenderModes(list):
    """The render modes an env's ``metadata`` declares: a list whose ``in`` refuses a mode
    that is not a string, with a ``ValueError`` naming ``render_mode`` and the value.
    ``gymnasium.make`` tests a requested mode with ``in`` and string methods before the env
    sees it, and would fail on a number with an error naming neither."""

    def __contains__(self, mode: object) -> bool:
        if not isinstance(mode, str):
            raise ValueError(f"render_mode must be None or one of {list(self)}, got {short(mode)}")
        return super().__contains__(mode)


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


def uncertainty_sds(value: Any) -> dict[str, float]:
    """``uncertainty`` as standard deviations by :data:`grasp_env.envs.uncertainty.
    UNCERTAINTY_KEYS` (a number is the vertices'; a dict gives any of them, the rest 0), each
    in [0, ``MAX_UNCERTAINTY``]."""
    if isinstance(value, dict):
        unknown = sorted(set(value) - set(UNCERTAINTY_KEYS), key=str)
        if unknown:
            raise ValueError(
                f"uncertainty: unknown key(s) {unknown}; allowed: {list(UNCERTAINTY_KEYS)}"
            )
        raw = {key: value.get(key, 0.0) for key in UNCERTAINTY_KEYS}
        names = {key: f"uncertainty[{key!r}]" for key in UNCERTAINTY_KEYS}
    else:
        raw = {key: value if key == "vertices" else 0.0 for key in UNCERTAINTY_KEYS}
        names = dict.fromkeys(UNCERTAINTY_KEYS, "uncertainty")
    return {
        key: number(raw[key], names[key], 0.0, MAX_UNCERTAINTY, lo_open=False)
        for key in UNCERTAINTY_KEYS
    }


def action_values(action: Any, size: int) -> list[float]:
    """An action as Python floats clipped into [-1, 1]; refused (``ValueError`` naming
    ``action``) unless it is finite real numbers of shape ``(size,)``."""
    if (
        type(action) is np.ndarray
        and action.dtype.kind == "f"
        and action.dtype.itemsize <= 8  # tolist() gives Python floats
        and action.shape == (size,)
    ):
        values = action.tolist()  # the common case, checked as real_vector would
        total = sum(values)  # finite only if every value is (or on overflow: see below)
        if total - total == 0.0 and -1.0 <= min(values) and max(values) <= 1.0:
            return values  # already in the action space
        if not all(map(math.isfinite, values)):
            raise ValueError(f"action must be finite, got {short(action)}")
    else:
        values = real_vector(action, "action", size).tolist()
    return [min(max(x, -1.0), 1.0) for x in values]


def batch_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """A batch of actions as float64, refused (``ValueError`` naming ``actions``) unless it is
    finite real numbers of ``shape`` (:func:`grasp_env.arguments.real_array`; the kernel
    clips them into [-1, 1])."""
    return real_array(actions, "actions", shape)


def env_scene(spec: Any, name: str, max_vertices: int, start: str, contact_tol: float) -> Scene:
    """The scene ``spec`` (argument ``name``) loaded and checked for the env: at most
    ``max_vertices`` vertices, its palm inside the palm workspace and, for a start other than
    ``"scene"``, room for the pre-liftoff hand set-up."""
    if not isinstance(spec, str | os.PathLike | dict | Scene):
        raise TypeError(
            f"{name} must be a bundled name, a path, a dict or a Scene, got {short(spec)}"
        )
    try:
        scene = load_scene(spec)
    except ValueError as exc:
        raise ValueError(f"{name} {spec_name(spec)}: {exc}") from None
    n = len(scene.object.vertices_B)
    if n > max_vertices:
        raise ValueError(
            f"{name} {spec_name(spec)}: the object has {n} vertices, more than "
            f"max_vertices={max_vertices}"
        )
    problem = palm_problem(scene, scene.palm.pose)
    if problem:
        raise ValueError(f"{name} {spec_name(spec)}: palm.pose {problem}")
    if start != "scene":
        problem = placement_problem(scene, scene.object.start_pose, hand_setup(scene), contact_tol)
        if problem:
            raise ValueError(
                f"{name} {spec_name(spec)}: start={start!r} needs the pre-liftoff hand "
                f"set-up, but there {problem}"
            )
    return scene


def shape_problem(scene: Scene, contact_tol: float) -> str | None:
    """Why a random shape's scene cannot start an episode (None if it can): its palm outside
    the palm workspace, or its hand set-up touching the object closer than the simulator's
    contact tolerance allows (the scene loader checks at the default one)."""
    problem = palm_problem(scene, scene.palm.pose)
    if problem:
        return f"palm.pose {problem}"
    return placement_problem(scene, scene.object.start_pose, scene.initial_hand, contact_tol)


#: The keys of ``reset(options=...)``.
OPTION_KEYS = ("scene", "palm", "fingers", "object_pose")


def reset_options(options: Any, load: Callable[[Any, str], Scene]) -> dict[str, Any]:
    """``reset``'s ``options`` checked: the scene loaded by ``load(spec, name)``, the palm
    pose, finger angles and object pose as arrays."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict or None, got {options!r}")
    unknown = sorted(set(options) - set(OPTION_KEYS), key=str)
    if unknown:
        raise ValueError(f"options: unknown key(s) {unknown}; allowed: {list(OPTION_KEYS)}")
    out: dict[str, Any] = {}
    if options.get("scene") is not None:
        try:
            out["scene"] = load(options["scene"], "options['scene']")
        except TypeError as exc:  # a refused reset argument is a ValueError, as for actions
            raise ValueError(str(exc)) from None
    for key, size in (("palm", 3), ("fingers", 2), ("object_pose", 3)):
        if options.get(key) is not None:
            out[key] = real_vector(options[key], f"options[{key!r}]", size)
    return out


def option_start(
    scene: Scene, opts: dict[str, Any], contact_tol: float
) -> tuple[np.ndarray, np.ndarray]:
    """The object pose and hand a start of checked reset options ``opts`` is settled from
    (missing parts from the scene): refused with the object's angle beyond 2 pi in magnitude,
    its centre or the palm outside the palm workspace, the fingers outside their joint
    limits, or a body overlapping another or the support."""
    pose = scene.object.start_pose.copy()
    if "object_pose" in opts:
        pose = opts["object_pose"]
        if abs(pose[2]) > MAX_ANGLE:  # the scene schema's bound on angles
            raise ValueError(
                f"options['object_pose'] {pose.tolist()}: its angle must be within [-2 pi, 2 pi]"
            )
        outside = workspace_problem(scene, pose[0], pose[1])
        if outside:  # a start the palm could reach, and a fall of bounded length
            raise ValueError(f"options['object_pose'] {pose.tolist()}: its centre {outside}")
    h = scene.initial_hand.copy()
    if "palm" in opts:
        problem = palm_problem(scene, opts["palm"])
        if problem:
            raise ValueError(f"options['palm'] {problem}")
        h[:3] = opts["palm"]
    if "fingers" in opts:
        lim = scene.joint_limits
        q = opts["fingers"]
        if np.any(q < lim[:, 0]) or np.any(q > lim[:, 1]):
            raise ValueError(
                f"options['fingers'] {q.tolist()} is outside the joint limits {lim.tolist()}"
            )
        h[3:] = q
    problem = placement_problem(scene, pose, h, contact_tol)
    if problem:
        raise ValueError(
            f"options palm={h[:3].tolist()}, fingers={h[3:].tolist()}, "
            f"object_pose={pose.tolist()} refused: {problem}"
        )
    return pose, h
