"""Scenes from dicts in the scene schema (docs/conventions.md), validated field by field:
every bad input raises :class:`~grasp_env.errors.SceneError` naming the field and the value.

Kept apart from the finding and reading of scene files (:mod:`grasp_env.core.scene_loading`):
the checks of a scene's fields, and of polygons (:func:`convex_polygon`), which other modules
use on their own. The accepted ranges are in :mod:`grasp_env.core.scene`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from grasp_env.arguments import is_real
from grasp_env.core import geometry as geo
from grasp_env.core.kinematics import hand_polygons_W
from grasp_env.core.scene import (
    DEFAULT_CONTACT_TOL,
    DENSITY_RANGE,
    GRAVITY_RANGE,
    LENGTH_RANGE,
    MAX_ANGLE,
    MAX_COORDINATE,
    MAX_TORQUE,
    MIN_EDGE_TOLS,
    PALM_WIDTH_RANGE,
    FingerSpec,
    ObjectSpec,
    PalmSpec,
    Scene,
)  # fmt: skip
from grasp_env.errors import SceneError

_TOP_KEYS = {"name", "description", "gravity", "palm", "fingers", "object"}
_PALM_KEYS = {"width", "thickness", "pose", "density"}
_FINGER_KEYS = {"length", "thickness", "angle", "limits", "torque_limits", "density"}
_OBJECT_KEYS = {"vertices", "density", "mass"}


def _number(
    value: Any, name: str, *, positive: bool = False, allow_inf: bool = False, angle: bool = False
) -> float:
    if not is_real(value):
        raise SceneError(f"{name} must be a number, got {value!r}")
    try:
        x = float(value)
    except OverflowError:
        raise SceneError(f"{name} must be finite, got {value!r}") from None
    if math.isnan(x) or (math.isinf(x) and not allow_inf):
        raise SceneError(f"{name} must be finite, got {value!r}")
    if positive and not x > 0:
        raise SceneError(f"{name} must be positive, got {value!r}")
    if angle and abs(x) > MAX_ANGLE:
        raise SceneError(
            f"{name} must be an angle in radians within [-2 pi, 2 pi], got {value!r} "
            "(degrees given?)"
        )
    return x


def _within(
    x: float, name: str, bounds: tuple[float, float], unit: str = "", per: float = 1.0
) -> float:
    """``x`` if it lies in ``bounds`` times ``per`` (``unit`` names ``per``), else SceneError."""
    lo, hi = bounds
    if lo * per <= x <= hi * per:
        return x
    rel = f" x {unit} = [{lo * per:g}, {hi * per:g}]" if unit else ""
    raise SceneError(f"{name} must be within [{lo:g}, {hi:g}]{rel}, got {x!r}")


def coordinate_problem(
    v: np.ndarray, name: str, width: float, bound: float = MAX_COORDINATE
) -> str | None:
    """Why ``v``, (n, 2) or (2,), has a coordinate beyond ``bound`` palm widths (None if it
    has none), naming the entry of ``name`` and showing its value."""
    bad = np.argwhere(np.abs(np.atleast_2d(v)) > bound * width)
    if not len(bad):
        return None
    i, j = (int(x) for x in bad[0])
    where = f"{name}[{i}][{j}]" if np.ndim(v) == 2 else f"{name}[{j}]"
    return (
        f"{where} must be within {bound:g} x palm.width = {bound * width:g} in magnitude, "
        f"got {float(np.atleast_2d(v)[i, j])!r}"
    )


def _coordinates(v: np.ndarray, name: str, width: float) -> None:
    """Refuse a coordinate beyond ``MAX_COORDINATE`` palm widths; ``v`` is (n, 2) or (2,)."""
    problem = coordinate_problem(v, name, width)
    if problem:
        raise SceneError(problem)


def _vector(
    value: Any, name: str, size: int, allow_inf: bool = False, angles: tuple[int, ...] = ()
) -> np.ndarray:
    """``size`` numbers; entries whose index is in ``angles`` are angles (see ``_number``)."""
    if not isinstance(value, list | tuple | np.ndarray) or len(value) != size:
        raise SceneError(f"{name} must be a list of {size} numbers, got {value!r}")
    return np.array(
        [
            _number(v, f"{name}[{i}]", allow_inf=allow_inf, angle=i in angles)
            for i, v in enumerate(value)
        ]
    )


def _check_keys(d: Any, allowed: set[str], required: set[str], name: str) -> None:
    if not isinstance(d, dict):
        raise SceneError(f"{name} must be a mapping, got {d!r}")
    unknown = sorted(set(d) - allowed, key=str)
    if unknown:
        raise SceneError(f"{name}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    missing = sorted(required - set(d))
    if missing:
        raise SceneError(f"{name}: missing key(s) {missing}")


def _length(d: dict, key: str, name: str, width: float, default: float | None = None) -> float:
    """``d[key]`` (or ``default``), positive and within ``LENGTH_RANGE`` palm widths."""
    x = _number(d.get(key, default), name, positive=True)
    unit = "palm.width" if key in d else "palm.width (default)"
    return _within(x, name, LENGTH_RANGE, unit, width)


def _density(d: dict, name: str) -> float:
    return _within(_number(d.get("density", 1.0), name, positive=True), name, DENSITY_RANGE)


def _palm(d: Any) -> PalmSpec:
    _check_keys(d, _PALM_KEYS, {"width", "pose"}, "palm")
    width = _within(
        _number(d["width"], "palm.width", positive=True), "palm.width", PALM_WIDTH_RANGE
    )
    pose = _vector(d["pose"], "palm.pose", 3, angles=(2,))
    _coordinates(pose[:2], "palm.pose", width)
    return PalmSpec(
        width=width,
        thickness=_length(d, "thickness", "palm.thickness", width, default=0.15),
        pose=pose,
        density=_density(d, "palm.density"),
    )


def _finger(d: Any, i: int, width: float) -> FingerSpec:
    name = f"fingers[{i}]"
    _check_keys(d, _FINGER_KEYS, {"length", "angle"}, name)
    limits = tuple(_vector(d.get("limits", [-math.pi, 0.0]), f"{name}.limits", 2, angles=(0, 1)))
    if not limits[0] < limits[1]:
        raise SceneError(f"{name}.limits must be increasing, got {[float(x) for x in limits]!r}")
    angle = _number(d["angle"], f"{name}.angle", angle=True)
    if not limits[0] - 1e-12 <= angle <= limits[1] + 1e-12:
        raise SceneError(
            f"{name}.angle {angle!r} is outside {name}.limits {[float(x) for x in limits]!r}"
        )
    torque = d.get("torque_limits")  # bounded relative to the weight in _check_torques
    if torque is None:
        torque_limits = (-math.inf, math.inf)
    else:
        torque_limits = tuple(_vector(torque, f"{name}.torque_limits", 2, allow_inf=True))
        if not torque_limits[0] < torque_limits[1]:
            raise SceneError(f"{name}.torque_limits must be increasing, got {torque!r}")
    return FingerSpec(
        length=_length(d, "length", f"{name}.length", width),
        thickness=_length(d, "thickness", f"{name}.thickness", width, default=0.05),
        angle=angle,
        limits=limits,  # type: ignore[arg-type]
        torque_limits=torque_limits,  # type: ignore[arg-type]
        density=_density(d, f"{name}.density"),
    )


#: Adjacent vertices this close, relative to the polygon's extent, are one point given twice.
SAME_POINT_TOL = 1e-9


def convex_polygon(raw: Any, name: str, width: float | None = None) -> np.ndarray:
    """``raw`` as a new ``(n, 2)`` float array: at least 3 points of two real, finite numbers,
    counter-clockwise, strictly convex, winding once (no star polygon) and no point repeated;
    else :class:`SceneError` naming ``name`` and showing the value.

    The scene's checks of ``object.vertices`` that do not depend on the rest of the scene, for
    every function that takes a polygon. With ``width`` (the palm width) coordinates beyond
    ``MAX_COORDINATE`` palm widths are refused too, before the shape checks, whose arithmetic
    such values could overflow.
    """
    if not isinstance(raw, list | tuple | np.ndarray) or len(raw) < 3:
        raise SceneError(f"{name} must be a list of at least 3 [x, y] points, got {raw!r}")
    v = np.array([_vector(p, f"{name}[{i}]", 2) for i, p in enumerate(raw)])
    if width is not None:
        _coordinates(v, name, width)
    scale = float(np.ptp(v, axis=0).max())
    _representable(v, scale, name)
    edge = geo.norms(geo.edge_vectors(v))
    least = SAME_POINT_TOL * max(scale, 1e-300)
    for i in np.flatnonzero(edge <= least):
        j = (i + 1) % len(v)
        raise SceneError(
            f"{name}[{i}] and [{j}] ({v[i].tolist()}, {v[j].tolist()}) are "
            f"{float(edge[i])!r} apart, within the tolerance of {SAME_POINT_TOL:g} x the "
            f"polygon's extent = {least!r}: they count as one point"
        )
    if geo.polygon_area(v) < 0:
        raise SceneError(f"{name} are clockwise; give them counter-clockwise: {v.tolist()}")
    if not geo.is_convex_ccw(v) or not geo.turns_once(v):
        raise SceneError(f"{name} do not form a strictly convex polygon: {_convexity_fault(v)}")
    return v


#: Largest coordinate and least extent (largest minus least coordinate) of a polygon: the
#: squares and products of its coordinates, which the shape checks and the analyses form,
#: stay within the normal range of doubles (about 1e-308 to 1e308).
POLYGON_RANGE = (1e-150, 1e150)


def _representable(v: np.ndarray, scale: float, name: str) -> None:
    """Refuse a polygon whose coordinates' squares would overflow, or whose extent's would
    underflow (a polygon of all one point is left to the repeated-point check)."""
    least, most = POLYGON_RANGE
    big = np.argwhere(np.abs(v) > most)
    if len(big):
        i, j = (int(x) for x in big[0])
        raise SceneError(
            f"{name}[{i}][{j}] must be within {most:g} in magnitude, got {float(v[i, j])!r}"
        )
    if 0.0 < scale < least:
        raise SceneError(
            f"{name} span {scale!r}, less than {least:g}: too small a polygon for double "
            f"precision (scale it up); vertices: {v.tolist()}"
        )


def _convexity_fault(v: np.ndarray) -> str:
    """Where the counter-clockwise polygon ``v`` fails to be strictly convex: the first vertex
    whose edges do not turn left, or that it winds round more than once."""
    d = geo.edge_vectors(v)
    turn = geo.cross2(d, geo.following(d))
    scale = geo.norms(d) * geo.norms(geo.following(d))
    for k in np.flatnonzero(turn <= 1e-12 * scale):
        i = (int(k) + 1) % len(v)
        bend = "turn right" if turn[k] < 0 else "run straight on"
        return f"its edges {bend} at vertex [{i}] {v[i].tolist()}; vertices: {v.tolist()}"
    return f"it winds round more than once (a star polygon); vertices: {v.tolist()}"


def _object(d: Any, width: float) -> ObjectSpec:
    _check_keys(d, _OBJECT_KEYS, {"vertices"}, "object")
    v = convex_polygon(d["vertices"], "object.vertices", width)
    if "density" in d and "mass" in d:
        raise SceneError(
            f"object: give either density ({d['density']!r}) or mass ({d['mass']!r}), not both"
        )
    size = "object.vertices: the object's size (largest extent)"
    _within(float(np.ptp(v, axis=0).max()), size, LENGTH_RANGE, "palm.width", width)
    area = geo.polygon_area(v)
    if "mass" in d:
        mass = _number(d["mass"], "object.mass", positive=True)
        if not DENSITY_RANGE[0] <= mass / area <= DENSITY_RANGE[1]:
            raise SceneError(
                f"object.mass {mass!r} gives a mean density (mass / area) of {mass / area!r}, "
                f"outside [{DENSITY_RANGE[0]:g}, {DENSITY_RANGE[1]:g}]"
            )
    else:
        mass = _density(d, "object.density") * area
    c = geo.polygon_centroid(v)
    v_B = v - c
    return ObjectSpec(
        vertices_B=v_B,
        start_pose=np.array([c[0], c[1], 0.0]),
        mass=mass,
        inertia=geo.polygon_inertia(v_B, mass),
    )


def _check_torques(scene: Scene) -> None:
    """Refuse finite torque limits beyond ``MAX_TORQUE`` object weights x palm widths."""
    bound = MAX_TORQUE * scene.object_weight * scene.palm.width
    for i, f in enumerate(scene.fingers):
        for j, tau in enumerate(f.torque_limits):
            if math.isfinite(tau) and abs(tau) > bound:
                raise SceneError(
                    f"fingers[{i}].torque_limits[{j}] must be within {MAX_TORQUE:g} x object "
                    f"weight x palm.width = {bound:g} in magnitude (.inf for no limit), "
                    f"got {float(tau)!r}"
                )


def _check_geometry(scene: Scene) -> None:
    """At the contact tolerance, refuse object edges shorter than ``MIN_EDGE_TOLS``
    tolerances, then an object below the support or inside the hand, and a hand inside the
    support."""
    tol = DEFAULT_CONTACT_TOL * scene.palm.width
    obj = scene.object.vertices_W0
    edge = geo.norms(geo.edge_vectors(obj))
    i = int(np.argmin(edge))
    if edge[i] < MIN_EDGE_TOLS * tol:
        j = (i + 1) % len(obj)
        raise SceneError(
            f"object.vertices[{i}] and [{j}] ({obj[i].tolist()}, {obj[j].tolist()}) are "
            f"{float(edge[i])!r} apart, less than {MIN_EDGE_TOLS:g} contact tolerances "
            f"({MIN_EDGE_TOLS * tol:g} = {MIN_EDGE_TOLS:g} x {DEFAULT_CONTACT_TOL:g} x palm.width)"
        )
    if obj[:, 1].min() < -tol:
        raise SceneError(
            "object.vertices: the object starts below the support "
            f"(lowest y = {float(obj[:, 1].min())!r})"
        )
    names = ("palm.pose", "fingers[0]", "fingers[1]")
    for name, poly in zip(names, hand_polygons_W(scene, scene.initial_hand), strict=True):
        if poly[:, 1].min() < -tol:
            raise SceneError(
                f"{name}: the hand starts inside the support "
                f"(lowest y = {float(poly[:, 1].min())!r})"
            )
        depth = geo.penetration_depth(poly, obj)
        if depth > tol:
            raise SceneError(f"{name}: the hand overlaps the object at the start by {depth!r}")


def scene_from_dict(d: Any, source: str | None = None) -> Scene:
    """Build and validate a :class:`Scene` from a dict in the scene schema (docs/conventions.md).

    Besides the schema, every quantity must lie in the ranges of the module docstring; a
    value outside raises :class:`SceneError` naming the field, the value and the range.
    """
    _check_keys(d, _TOP_KEYS, {"palm", "fingers", "object"}, "scene")
    fingers = d["fingers"]
    if not isinstance(fingers, list | tuple) or len(fingers) != 2:
        raise SceneError(f"fingers must be a list of exactly two fingers, got {fingers!r}")
    name = d.get("name", "unnamed")
    if not isinstance(name, str):
        raise SceneError(f"name must be a string, got {name!r}")
    gravity = _within(
        _number(d.get("gravity", 9.81), "gravity", positive=True), "gravity", GRAVITY_RANGE
    )
    palm = _palm(d["palm"])
    w = palm.width
    scene = Scene(
        name=name,
        gravity=gravity,
        palm=palm,
        fingers=(_finger(fingers[0], 0, w), _finger(fingers[1], 1, w)),
        object=_object(d["object"], w),
        description=str(d.get("description", "")),
        source=source,
    )
    _check_torques(scene)
    _check_geometry(scene)
    return scene
