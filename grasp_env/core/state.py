"""Simulation state: immutable snapshots of the object pose, hand configuration and contacts.

A contact is a vertex of one body on an edge of another (docs/conventions.md, "Contacts"). It
is identified by a key ``(body, kind, object_feature, hand_feature)``:

* kind ``EDGE`` (``"edge"``): object vertex ``object_feature`` on edge ``hand_feature`` of the
  hand body (for the support, the line y = 0, ``hand_feature = 0``); the contact point is fixed
  in the object frame and the normal is the hand edge's outward normal.
* kind ``TIP`` (``"tip"``): hand vertex ``hand_feature`` (usually a fingertip) on object edge
  ``object_feature`` (from vertex k to k+1); the point is fixed in the hand body's frame and the
  normal is the object edge's inward normal.

Normals always point into the object; gaps are positive when the bodies are apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np

from grasp_env.arguments import integer, number, real_vector, short
from grasp_env.core.geometry import BODY_NAMES
from grasp_env.core.scene import Scene

EDGE, TIP = 0, 1
KIND_NAMES = ("edge", "tip")
#: How far from 1 the length of a contact normal built by hand may be.
UNIT_TOL = 1e-9

#: The names a contact's body and kind, and an event's kind, take.
BodyName = Literal["support", "palm", "finger1", "finger2"]
ContactKind = Literal["edge", "tip"]
EventKind = Literal[
    "new_contact", "edge_to_tip", "tip_to_edge", "lost_contact", "fall_start", "fall_end",
    "jam", "joint_limit", "hand_blocked",
]  # fmt: skip


class ContactKey(NamedTuple):
    """A contact's identity: its body (:data:`grasp_env.core.geometry.BODY_NAMES` index),
    kind (``EDGE`` or ``TIP``) and the object and hand features it joins (see
    :class:`Contact`). A tuple, so it compares and hashes as the plain 4-tuple."""

    body: int
    kind: int
    object_feature: int
    hand_feature: int


@dataclass(frozen=True)
class Contact:
    """A contact of a returned state (public API, docs/conventions.md).

    Attributes:
        body: ``"support"``, ``"palm"``, ``"finger1"`` or ``"finger2"``.
        kind: ``"edge"`` (object vertex on a hand edge) or ``"tip"`` (hand vertex on an
            object edge).
        point: contact point in the world, shape (2,).
        normal: unit normal into the object, world frame, shape (2,).
        force: contact force magnitude ``c >= 0``; the force on the object is ``c * normal``.
        object_feature: object vertex (edge kind) or object edge index (tip kind).
        hand_feature: hand edge (edge kind; 0 for the support) or hand vertex index (tip kind).
        gap: signed gap at the returned state (``|gap| <= contact_tol``).
    """

    body: BodyName
    kind: ContactKind
    point: np.ndarray
    normal: np.ndarray
    force: float
    object_feature: int
    hand_feature: int
    gap: float = 0.0

    def __post_init__(self) -> None:
        """Check a contact built by hand (the simulator fills in its own directly)."""
        if self.body not in BODY_NAMES:
            raise ValueError(f"contact body must be one of {list(BODY_NAMES)}, got {self.body!r}")
        if self.kind not in KIND_NAMES:
            raise ValueError(f"contact kind must be one of {list(KIND_NAMES)}, got {self.kind!r}")
        point = real_vector(self.point, "contact point", 2)
        normal = real_vector(self.normal, "contact normal", 2)
        if abs(math.hypot(*normal) - 1.0) > UNIT_TOL:
            raise ValueError(f"contact normal must be a unit vector, got {normal.tolist()}")
        object.__setattr__(self, "point", read_only(point))
        object.__setattr__(self, "normal", read_only(normal))
        # plain Python numbers, as the simulator's own contacts hold
        for name in ("object_feature", "hand_feature"):
            value = integer(getattr(self, name), f"contact {name}", 0, TypeError)
            object.__setattr__(self, name, value)
        force = number(self.force, "contact force", 0.0, math.inf, False, True)
        object.__setattr__(self, "force", force)
        gap = number(self.gap, "contact gap", -math.inf, math.inf, True, True)
        object.__setattr__(self, "gap", gap)

    def __setstate__(self, fields: dict) -> None:
        """Unpickled, as made: its arrays read-only."""
        self.__dict__.update(fields, point=read_only(fields["point"]),
                             normal=read_only(fields["normal"]))  # fmt: skip

    @property
    def key(self) -> ContactKey:
        return ContactKey(
            BODY_NAMES.index(self.body),
            KIND_NAMES.index(self.kind),
            self.object_feature,
            self.hand_feature,
        )

    def as_dict(self) -> dict:
        return {
            "body": self.body,
            "kind": self.kind,
            "point": self.point.copy(),
            "normal": self.normal.copy(),
            "force": self.force,
        }


@dataclass(frozen=True)
class Event:
    """Something that happened during a hand move.

    Attributes:
        kind: one of ``"new_contact"``, ``"edge_to_tip"``, ``"tip_to_edge"``, ``"lost_contact"``,
            ``"fall_start"``, ``"fall_end"``, ``"jam"``, ``"joint_limit"``, ``"hand_blocked"``.
        s: path parameter in [0, 1] along the straight-line hand move where it happened.
        contacts: the contacts involved, as ``(body, kind, object_feature, hand_feature)`` keys.
    """

    kind: EventKind
    s: float
    contacts: tuple[ContactKey, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "s", float(self.s))  # a plain float, not a numpy scalar


@dataclass(frozen=True, eq=False)
class State:
    """Object pose, hand configuration and contacts (with forces) at rest (public API,
    docs/conventions.md). A snapshot: its arrays and its contacts' are read-only, and a
    state built by hand copies the arrays it is given.

    Attributes:
        scene: the scene this state belongs to.
        object_pose: object centre-of-mass pose ``(x, y, theta)`` in the world, shape (3,).
        hand: hand configuration ``(x_p, y_p, theta_p, q1, q2)``, shape (5,).
        contacts: the contacts, each with its force.
        jammed: the hand stopped short of its target because the object could not get out of
            the way (the velocity LP became infeasible).
        hand_blocked: the hand stopped short of its target because it would enter the support.
        events: what happened during the move that produced this state.
    """

    scene: Scene
    object_pose: np.ndarray
    hand: np.ndarray
    contacts: tuple[Contact, ...] = ()
    jammed: bool = False
    hand_blocked: bool = False
    events: tuple[Event, ...] = field(default=())
    #: :meth:`contact_arrays`, kept once gathered (the simulator sets its own,
    #: :func:`keep_contact_arrays`); not a constructor argument, so a copy made with other
    #: contacts (``dataclasses.replace``) gathers its own.
    _arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(
        default=None, init=False, repr=False
    )
    #: Whether the state was built by hand (its constructor ran), not made by a simulator:
    #: a simulator checks such a state before it moves from it.
    _by_hand: bool = field(default=False, init=False, repr=False)

    def __post_init__(self) -> None:
        """Check a state built by hand (the simulator fills in its own directly)."""
        if not isinstance(self.scene, Scene):
            raise TypeError(f"state scene must be a grasp_env.Scene, got {short(self.scene)}")
        for name, size in (("object_pose", 3), ("hand", 5)):  # copies, as the state's own
            object.__setattr__(self, name, read_only(real_vector(getattr(self, name), name, size)))
        object.__setattr__(self, "contacts", _items(self.contacts, "contacts", Contact))
        object.__setattr__(self, "events", _items(self.events, "events", Event))
        for name in ("jammed", "hand_blocked"):
            value = getattr(self, name)
            if not isinstance(value, bool | np.bool_):
                raise TypeError(f"state {name} must be a bool, got {short(value)}")
            object.__setattr__(self, name, bool(value))
        object.__setattr__(self, "_by_hand", True)

    def __setstate__(self, fields: dict) -> None:
        """Unpickled, as made: its arrays read-only."""
        self.__dict__.update(fields, object_pose=read_only(fields["object_pose"]),
                             hand=read_only(fields["hand"]))  # fmt: skip

    @property
    def on_support(self) -> bool:
        """Whether the object touches the support."""
        for c in self.contacts:
            if c.body == "support":
                return True
        return False

    @property
    def palm_pose(self) -> np.ndarray:
        return self.hand[:3]

    @property
    def finger_angles(self) -> np.ndarray:
        return self.hand[3:]

    def contact_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points (n, 2), normals (n, 2) and body indices (n,) of the contacts (new arrays
        each call)."""
        if self._arrays is None:
            n = len(self.contacts)
            pts = np.array([c.point for c in self.contacts], dtype=float).reshape(n, 2)
            nrm = np.array([c.normal for c in self.contacts], dtype=float).reshape(n, 2)
            bodies = np.array([BODY_NAMES.index(c.body) for c in self.contacts], dtype=int)
            keep_contact_arrays(self, pts, nrm, bodies)
        pts, nrm, bodies = self._arrays
        return pts.copy(), nrm.copy(), bodies.copy()


def _items(value: object, name: str, kind: type) -> tuple:
    """``value`` as a tuple of ``kind`` objects, else ``TypeError`` naming ``name``."""
    try:
        items = tuple(value)  # type: ignore[call-overload]
    except TypeError:
        raise TypeError(
            f"state {name} must be a sequence of grasp_env.{kind.__name__}, got {short(value)}"
        ) from None
    for item in items:
        if not isinstance(item, kind):
            raise TypeError(f"state {name} must be grasp_env.{kind.__name__}, got {short(item)}")
    return items


def require_state(state: object) -> None:
    """Refuse anything but a :class:`State` (a state built by hand checks its own fields)."""
    if not isinstance(state, State):
        raise TypeError(
            f"state must be a grasp_env.State, got {type(state).__name__} {short(state)}"
        )


def new_state(
    scene: Scene,
    object_pose: np.ndarray,
    hand: np.ndarray,
    contacts: tuple[Contact, ...],
    jammed: bool,
    hand_blocked: bool,
    events: tuple[Event, ...],
) -> State:
    """``State(scene, object_pose, hand, contacts, jammed, hand_blocked, events)``, filled in
    directly (as :func:`contacts_from_arrays` fills in contacts): the simulator makes one at
    every move."""
    state = _new_object(State)
    state.__dict__.update(
        scene=scene, object_pose=read_only(object_pose), hand=read_only(hand),
        contacts=contacts, jammed=jammed, hand_blocked=hand_blocked, events=events,
    )  # fmt: skip
    return state


def contacts_from_arrays(
    keys: list, points: np.ndarray, normals: np.ndarray, forces: list, gaps: list
) -> tuple[Contact, ...]:
    """Contacts from the simulator's arrays: ``keys`` as ``(body, kind, object_feature,
    hand_feature)`` index rows, ``points`` and ``normals`` (n, 2) (each contact's are views
    of a row), ``forces`` and ``gaps`` as floats. The same objects as ``Contact(...)`` makes,
    filled in directly: a frozen dataclass's ``__init__`` sets each field through
    ``object.__setattr__``, and this runs at every simulated step."""
    out = []
    points, normals = read_only(points), read_only(normals)  # each contact's rows: views
    for i, (body, kind, object_feature, hand_feature) in enumerate(keys):
        c = _new_object(Contact)
        c.__dict__.update(
            body=BODY_NAMES[body], kind=KIND_NAMES[kind], point=points[i], normal=normals[i],
            force=forces[i], object_feature=object_feature, hand_feature=hand_feature,
            gap=gaps[i],
        )  # fmt: skip
        out.append(c)
    return tuple(out)


_new_object = object.__new__


def read_only(a: np.ndarray) -> np.ndarray:
    """A view of ``a`` that cannot be written to: a state and its contacts are snapshots
    (``a`` itself stays writeable for its owner)."""
    view = a.view()
    view.flags.writeable = False
    return view


def keep_contact_arrays(
    state: State, points: np.ndarray, normals: np.ndarray, bodies: np.ndarray
) -> State:
    """``state`` holding its contacts' points (n, 2), normals (n, 2) and body indices (n,)
    for :meth:`State.contact_arrays` (they must be its contacts', in order)."""
    object.__setattr__(state, "_arrays", (points, normals, bodies))
    return state
