"""Scene description: the hand, the object and gravity, loaded once from YAML and validated.

The schema is DESIGN.md section 3. :func:`load_scene` accepts a bundled scene name (a file in
``configs/scenes/``), a path to a YAML file, or a dict in the same schema. Every bad input
raises :class:`~grasp_env.errors.SceneError` naming the field and the value.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from grasp_env import geometry as geo
from grasp_env.errors import SceneError

#: Folder of the bundled scenes (``GRASP_ENV_SCENES`` overrides it).
SCENES_DIR = Path(
    os.environ.get("GRASP_ENV_SCENES", Path(__file__).resolve().parents[1] / "configs" / "scenes")
)

#: Gap below which two bodies count as touching when a scene is checked, as a fraction of the
#: palm width (the simulator's default ``contact_tol``).
DEFAULT_CONTACT_TOL = 1e-9

#: Largest magnitude of any number in a scene, and smallest of a positive one (lengths,
#: densities, masses, gravity): products such as ``mass * length**2`` must stay finite and
#: normal floats, so that forces, inertias and tolerances derived from them do too.
MAX_MAGNITUDE = 1e100
MIN_POSITIVE = 1e-100

#: Largest magnitude of an angle (rad). Beyond one turn an angle is almost surely given in
#: degrees (e.g. limits ``[-180, 0]``).
MAX_ANGLE = 2 * math.pi

#: Shortest object edge, in contact tolerances (``DEFAULT_CONTACT_TOL`` x palm width): an
#: edge shorter than a few tolerances cannot be told apart from a vertex.
MIN_EDGE_TOLS = 10.0


@dataclass(frozen=True)
class PalmSpec:
    """The palm: a rectangle ``[-w/2, w/2] x [0, thickness]`` in its own frame P."""

    width: float
    thickness: float
    pose: np.ndarray  # (3,) initial world pose (x, y, theta)
    density: float

    @property
    def mass(self) -> float:
        return self.density * self.width * self.thickness


@dataclass(frozen=True)
class FingerSpec:
    """A single-link finger hinged at its joint on the palm's palmar edge."""

    length: float
    thickness: float
    angle: float  # initial joint angle q_i (rad), in the palm frame
    limits: tuple[float, float]  # joint limits (rad)
    torque_limits: tuple[float, float]  # joint torque limits (inf when unlimited)
    density: float

    @property
    def mass(self) -> float:
        return self.density * self.length * self.thickness

    def polygon_local(self, finger: int) -> np.ndarray:
        return geo.finger_polygon_local(self.length, self.thickness, finger)


@dataclass(frozen=True)
class ObjectSpec:
    """A convex polygon of uniform density; its frame O sits at the centroid."""

    vertices_B: np.ndarray  # (n, 2) CCW vertices in O
    start_pose: np.ndarray  # (3,) world pose (x, y, 0) at the scene placement
    mass: float
    inertia: float  # about the centroid

    @property
    def vertices_W0(self) -> np.ndarray:
        """Vertices in the world at the scene placement, shape (n, 2)."""
        return self.vertices_B + self.start_pose[:2]


@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene: the hand, the object, gravity and the initial configuration."""

    name: str
    gravity: float
    palm: PalmSpec
    fingers: tuple[FingerSpec, FingerSpec]
    object: ObjectSpec
    description: str = ""
    source: str | None = field(default=None, compare=False)

    @property
    def initial_hand(self) -> np.ndarray:
        """Hand configuration ``(x_p, y_p, theta_p, q1, q2)`` of the scene, shape (5,)."""
        return np.array([*self.palm.pose, self.fingers[0].angle, self.fingers[1].angle])

    @property
    def object_weight(self) -> float:
        return self.object.mass * self.gravity

    @property
    def joint_limits(self) -> np.ndarray:
        """Finger joint limits, shape (2, 2): row i is (lower, upper) of finger i+1."""
        return np.array([f.limits for f in self.fingers])


_TOP_KEYS = {"name", "description", "gravity", "palm", "fingers", "object"}
_PALM_KEYS = {"width", "thickness", "pose", "density"}
_FINGER_KEYS = {"length", "thickness", "angle", "limits", "torque_limits", "density"}
_OBJECT_KEYS = {"vertices", "density", "mass"}


def _number(
    value: Any, name: str, *, positive: bool = False, allow_inf: bool = False, angle: bool = False
) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise SceneError(f"{name} must be a number, got {value!r}")
    try:
        x = float(value)
    except OverflowError:
        raise SceneError(f"{name} must be finite, got {value!r}") from None
    if math.isnan(x) or (math.isinf(x) and not allow_inf):
        raise SceneError(f"{name} must be finite, got {value!r}")
    if positive and not x > 0:
        raise SceneError(f"{name} must be positive, got {value!r}")
    if math.isfinite(x) and abs(x) > MAX_MAGNITUDE:
        raise SceneError(f"{name} must be at most {MAX_MAGNITUDE:g} in magnitude, got {value!r}")
    if positive and x < MIN_POSITIVE:
        raise SceneError(f"{name} must be at least {MIN_POSITIVE:g}, got {value!r}")
    if angle and abs(x) > MAX_ANGLE:
        raise SceneError(
            f"{name} must be an angle in radians within [-2 pi, 2 pi], got {value!r} "
            "(degrees given?)"
        )
    return x


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


def _palm(d: Any) -> PalmSpec:
    _check_keys(d, _PALM_KEYS, {"width", "pose"}, "palm")
    return PalmSpec(
        width=_number(d["width"], "palm.width", positive=True),
        thickness=_number(d.get("thickness", 0.15), "palm.thickness", positive=True),
        pose=_vector(d["pose"], "palm.pose", 3, angles=(2,)),
        density=_number(d.get("density", 1.0), "palm.density", positive=True),
    )


def _finger(d: Any, i: int) -> FingerSpec:
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
    torque = d.get("torque_limits")
    if torque is None:
        torque_limits = (-math.inf, math.inf)
    else:
        torque_limits = tuple(_vector(torque, f"{name}.torque_limits", 2, allow_inf=True))
        if not torque_limits[0] < torque_limits[1]:
            raise SceneError(f"{name}.torque_limits must be increasing, got {torque!r}")
    return FingerSpec(
        length=_number(d["length"], f"{name}.length", positive=True),
        thickness=_number(d.get("thickness", 0.05), f"{name}.thickness", positive=True),
        angle=angle,
        limits=limits,  # type: ignore[arg-type]
        torque_limits=torque_limits,  # type: ignore[arg-type]
        density=_number(d.get("density", 1.0), f"{name}.density", positive=True),
    )


def _object(d: Any) -> ObjectSpec:
    _check_keys(d, _OBJECT_KEYS, {"vertices"}, "object")
    raw = d["vertices"]
    if not isinstance(raw, list | tuple | np.ndarray) or len(raw) < 3:
        raise SceneError(f"object.vertices must be a list of at least 3 [x, y] points, got {raw!r}")
    v = np.array([_vector(p, f"object.vertices[{i}]", 2) for i, p in enumerate(raw)])
    edge = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
    scale = float(np.ptp(v, axis=0).max())
    for i in np.flatnonzero(edge <= 1e-9 * max(scale, 1e-300)):
        j = (i + 1) % len(v)
        raise SceneError(f"object.vertices[{i}] and [{j}] repeat the point {v[i].tolist()}")
    area = geo.polygon_area(v)
    if area < 0:
        raise SceneError(
            f"object.vertices are clockwise; give them counter-clockwise: {v.tolist()}"
        )
    if not geo.is_convex_ccw(v) or not geo.turns_once(v):
        raise SceneError(f"object.vertices do not form a strictly convex polygon: {v.tolist()}")
    if "density" in d and "mass" in d:
        raise SceneError(
            f"object: give either density ({d['density']!r}) or mass ({d['mass']!r}), not both"
        )
    if "mass" in d:
        mass = _number(d["mass"], "object.mass", positive=True)
    else:
        mass = _number(d.get("density", 1.0), "object.density", positive=True) * area
    c = geo.polygon_centroid(v)
    v_B = v - c
    return ObjectSpec(
        vertices_B=v_B,
        start_pose=np.array([c[0], c[1], 0.0]),
        mass=mass,
        inertia=geo.polygon_inertia(v_B, mass),
    )


def _check_sizes(scene: Scene) -> None:
    """Refuse object edges shorter than ``MIN_EDGE_TOLS`` contact tolerances, and derived
    masses, weights or inertias that are not finite positive normal floats."""
    tol = DEFAULT_CONTACT_TOL * scene.palm.width
    v = scene.object.vertices_W0
    edge = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
    i = int(np.argmin(edge))
    if edge[i] < MIN_EDGE_TOLS * tol:
        j = (i + 1) % len(v)
        raise SceneError(
            f"object.vertices[{i}] and [{j}] ({v[i].tolist()}, {v[j].tolist()}) are "
            f"{float(edge[i])!r} apart, less than {MIN_EDGE_TOLS:g} contact tolerances "
            f"({MIN_EDGE_TOLS * tol:g} = {MIN_EDGE_TOLS:g} x {DEFAULT_CONTACT_TOL:g} x palm.width)"
        )
    derived = {
        "palm mass (palm.density x width x thickness)": scene.palm.mass,
        "fingers[0] mass": scene.fingers[0].mass,
        "fingers[1] mass": scene.fingers[1].mass,
        "object mass": scene.object.mass,
        "object weight (mass x gravity)": scene.object_weight,
        "object inertia": scene.object.inertia,
    }
    for what, x in derived.items():
        if not (math.isfinite(x) and MIN_POSITIVE**2 <= x <= MAX_MAGNITUDE**2):
            raise SceneError(f"{what} is {x!r}: out of the range of representable quantities")


def _check_placement(scene: Scene) -> None:
    """Refuse an object below the support or inside the hand, and a hand inside the support."""
    from grasp_env.kinematics import hand_polygons_W  # local: kinematics imports scene types

    tol = DEFAULT_CONTACT_TOL * scene.palm.width
    obj = scene.object.vertices_W0
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
    """Build and validate a :class:`Scene` from a dict in the schema of DESIGN.md section 3."""
    _check_keys(d, _TOP_KEYS, {"palm", "fingers", "object"}, "scene")
    fingers = d["fingers"]
    if not isinstance(fingers, list | tuple) or len(fingers) != 2:
        raise SceneError(f"fingers must be a list of exactly two fingers, got {fingers!r}")
    name = d.get("name", "unnamed")
    if not isinstance(name, str):
        raise SceneError(f"name must be a string, got {name!r}")
    scene = Scene(
        name=name,
        gravity=_number(d.get("gravity", 9.81), "gravity", positive=True),
        palm=_palm(d["palm"]),
        fingers=(_finger(fingers[0], 0), _finger(fingers[1], 1)),
        object=_object(d["object"]),
        description=str(d.get("description", "")),
        source=source,
    )
    _check_sizes(scene)
    _check_placement(scene)
    return scene


def bundled_scenes() -> list[str]:
    """Names of the scenes shipped in ``configs/scenes/``."""
    return sorted(p.stem for p in SCENES_DIR.glob("*.yaml"))


def load_scene(spec: str | os.PathLike | dict | Scene) -> Scene:
    """Load a scene from a bundled name, a YAML path, a dict, or pass a :class:`Scene` through.

    Raises:
        SceneError: the file is missing or unreadable, or a field is invalid (the message
            names the field and the value).
    """
    if isinstance(spec, Scene):
        return spec
    if isinstance(spec, dict):
        return scene_from_dict(spec)
    if not isinstance(spec, str | os.PathLike):
        raise SceneError(f"scene must be a bundled name, a path or a dict, got {spec!r}")
    path = Path(spec)
    if not path.exists() and (SCENES_DIR / path.name).exists() and path.parent == Path("."):
        path = SCENES_DIR / path.name
    if not path.suffix and not path.exists():
        path = SCENES_DIR / f"{spec}.yaml"
        if not path.exists():
            raise SceneError(
                f"scene {str(spec)!r} is not a bundled scene; bundled: {bundled_scenes()}"
            )
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError(f"scene file {str(path)!r} cannot be read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"scene file {str(path)!r} is not UTF-8 text: {exc.reason}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise SceneError(f"scene file {str(path)!r} is not valid YAML: {exc}") from None
    return scene_from_dict(data, source=str(path))
