"""Scene description: the hand, the object and gravity (loaded and validated by
:mod:`grasp_env.core.scene_loading`).

The schema, with an annotated example, is in docs/conventions.md ("Scene schema").

Accepted ranges (docs/reliability.md, "Scene ranges"). The simulator and the analysis work in
units of the palm width ``w`` (lengths, the contact tolerance) and the object's weight ``W``
(forces), so only the palm width, gravity and the densities are bounded absolutely, each
over many more decades than any real hand needs in any unit system; the rest is bounded
relative to ``w`` and ``W`` by what double precision resolves against the contact tolerance
(``1e-9 w``) and the LP tolerances (``1e-7`` relative):

* ``palm.width``: ``PALM_WIDTH_RANGE`` = [1e-6, 1e6];
* ``palm.thickness``, ``fingers[i].length`` and ``.thickness``, the object's size (largest
  extent of its vertices): ``LENGTH_RANGE`` = [1e-3, 1e3] x ``w``;
* ``palm.pose`` x and y, object vertex coordinates: at most ``MAX_COORDINATE`` = 1e4 x ``w``
  in magnitude;
* ``gravity``: ``GRAVITY_RANGE`` = [1e-9, 1e9];
* densities, and mass / area for an object given by its mass: ``DENSITY_RANGE`` = [1e-9, 1e9];
* finite torque limits: at most ``MAX_TORQUE`` = 1e9 x ``W w`` in magnitude;
* angles (``palm.pose[2]``, joint angles and limits): at most ``MAX_ANGLE`` = 2 pi in magnitude.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from grasp_env.core import geometry as geo

#: Gap below which two bodies count as touching when a scene is checked, as a fraction of the
#: palm width (the simulator's default ``contact_tol``).
DEFAULT_CONTACT_TOL = 1e-9

#: Palm width, the length unit of the contact tolerance and of every relative range below:
#: a micrometre to 1000 km in metres; a 10 cm hand fits in any unit from micrometres to km.
PALM_WIDTH_RANGE = (1e-6, 1e6)

#: Palm thickness, finger lengths and thicknesses and the object's size, in palm widths: a
#: body 1e-3 w thin is still 1e6 contact tolerances thick.
LENGTH_RANGE = (1e-3, 1e3)

#: Largest coordinate (palm position, object vertices), in palm widths: rounding of a
#: position (``1e4 w x 2.2e-16``) stays 450 times below the contact tolerance (``1e-9 w``).
MAX_COORDINATE = 1e4

#: Gravity and the bodies' densities (mass per unit area; for an object given by its mass,
#: mass / area). The analysis works in units of the object's weight, so these only need
#: finite products; the bounds leave room for any unit system.
GRAVITY_RANGE = (1e-9, 1e9)
DENSITY_RANGE = (1e-9, 1e9)

#: Largest finite joint torque limit, in object weights x palm widths (the grip LP's torque
#: unit). A larger one could bind only at contact forces above 1e9 weights, beyond what a
#: grasp resolved to the contact tolerance needs: give ``.inf`` instead.
MAX_TORQUE = 1e9

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
