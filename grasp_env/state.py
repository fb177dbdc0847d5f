"""Simulation state: immutable snapshots of the object pose, hand configuration and contacts."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from grasp_env.contacts import Contact
from grasp_env.geometry import BODY_NAMES
from grasp_env.scene import Scene


@dataclass(frozen=True)
class Event:
    """Something that happened during a hand move.

    Attributes:
        kind: one of ``"new_contact"``, ``"edge_to_tip"``, ``"tip_to_edge"``, ``"lost_contact"``,
            ``"fall_start"``, ``"fall_end"``, ``"jam"``, ``"joint_limit"``, ``"hand_blocked"``.
        s: path parameter in [0, 1] along the straight-line hand move where it happened.
        contacts: the contacts involved, as ``(body, kind, object_feature, hand_feature)`` keys.
    """

    kind: str
    s: float
    contacts: tuple[tuple[int, int, int, int], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "s", float(self.s))  # a plain float, not a numpy scalar


@dataclass(frozen=True, eq=False)
class State:
    """Object pose, hand configuration and contacts (with forces) at rest (public API,
    docs/conventions.md).

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

    @property
    def on_support(self) -> bool:
        """Whether the object touches the support."""
        return any(c.body == "support" for c in self.contacts)

    @property
    def palm_pose(self) -> np.ndarray:
        return self.hand[:3]

    @property
    def finger_angles(self) -> np.ndarray:
        return self.hand[3:]

    def contact_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points (n, 2), normals (n, 2) and body indices (n,) of the contacts."""
        n = len(self.contacts)
        pts = np.array([c.point for c in self.contacts]).reshape(n, 2)
        nrm = np.array([c.normal for c in self.contacts]).reshape(n, 2)
        bodies = np.array([BODY_NAMES.index(c.body) for c in self.contacts], dtype=int)
        return pts, nrm, bodies
