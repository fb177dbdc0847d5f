"""Hand kinematics: world poses, polygons and point velocities of the palm and fingers.

A hand configuration is ``h = (x_p, y_p, theta_p, q1, q2)`` (shape (5,)); a hand velocity
(or increment) ``dh`` has the same layout. Hand bodies are numbered as in
:data:`grasp_env.core.geometry.BODY_NAMES`: 1 palm, 2 finger 1, 3 finger 2.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from grasp_env.core import geometry as geo

if TYPE_CHECKING:
    from grasp_env.core.scene import Scene


@lru_cache(maxsize=64)
def hand_polygons_local(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CCW polygons of palm, finger 1 and finger 2 in their own frames (palm P, link frames)."""
    return (
        geo.palm_polygon_local(scene.palm.width, scene.palm.thickness),
        scene.fingers[0].polygon_local(1),
        scene.fingers[1].polygon_local(2),
    )


def body_poses_W(scene: Scene, h: np.ndarray) -> np.ndarray:
    """World poses ``(x, y, phi)`` of palm, finger 1 and finger 2 frames, shape (3, 3)."""
    xp, yp, thp = h[0], h[1], h[2]
    c, s = math.cos(thp), math.sin(thp)
    half = scene.palm.width / 2.0
    return np.array(
        [
            [xp, yp, thp],
            [xp - c * half, yp - s * half, thp + h[3]],
            [xp + c * half, yp + s * half, thp + h[4]],
        ]
    )


def hand_units(scene: Scene) -> np.ndarray:
    """The unit of each hand coordinate ``(x_p, y_p, theta_p, q1, q2)``: the palm width for
    the palm's position, a radian for the angles. A hand difference divided by it compares
    with a scale-free tolerance."""
    w = scene.palm.width
    return np.array([w, w, 1.0, 1.0, 1.0])


def hand_polygons_W(scene: Scene, h: np.ndarray) -> list[np.ndarray]:
    """World polygons (CCW) of palm, finger 1 and finger 2 for hand configuration ``h``."""
    poses = body_poses_W(scene, h)
    return [
        geo.transform(pose, poly)
        for pose, poly in zip(poses, hand_polygons_local(scene), strict=True)
    ]


def body_twists_W(scene: Scene, h: np.ndarray, dh: np.ndarray) -> np.ndarray:
    """Twists ``(vx, vy, omega)`` of the palm and finger frames' origins for ``dh``, shape (3, 3).

    A finger's frame origin is its joint, which moves with the palm.
    """
    poses = body_poses_W(scene, h)
    v_palm = dh[:2]
    out = np.empty((3, 3))
    out[0] = (v_palm[0], v_palm[1], dh[2])
    for i in (1, 2):
        r = poses[i, :2] - poses[0, :2]
        out[i] = (v_palm[0] - dh[2] * r[1], v_palm[1] + dh[2] * r[0], dh[2] + dh[2 + i])
    return out


def point_velocity_W(
    scene: Scene, h: np.ndarray, dh: np.ndarray, body: int, p_W: np.ndarray
) -> np.ndarray:
    """Velocity (2,) of the material point of hand body ``body`` at world point ``p_W``.

    ``body`` uses :data:`grasp_env.core.geometry.BODY_NAMES` numbering; the support never moves.
    """
    if body == geo.SUPPORT:
        return np.zeros(2)
    poses = body_poses_W(scene, h)
    tw = body_twists_W(scene, h, dh)[body - 1]
    r = p_W - poses[body - 1, :2]
    return np.array([tw[0] - tw[2] * r[1], tw[1] + tw[2] * r[0]])


def fingertips_W(scene: Scene, h: np.ndarray) -> np.ndarray:
    """World positions of the two fingertips, shape (2, 2)."""
    poses = body_poses_W(scene, h)
    return np.array(
        [
            poses[1 + i, :2]
            + scene.fingers[i].length
            * np.array([math.cos(poses[1 + i, 2]), math.sin(poses[1 + i, 2])])
            for i in range(2)
        ]
    )


def hand_placement_problem(
    scene: Scene, object_pose: np.ndarray, h: np.ndarray, tol: float
) -> str | None:
    """Why hand configuration ``h`` is not allowed with the object at ``object_pose``, or None
    if it is: the object or a hand body entering the support, or a hand body overlapping the
    object, by more than ``tol`` (a length)."""
    obj = geo.transform(object_pose, scene.object.vertices_B)
    lowest = float(obj[:, 1].min())
    if lowest < -tol:
        return f"the object enters the support (lowest y = {lowest!r})"
    names = ("palm", "finger 1", "finger 2")
    for name, poly in zip(names, hand_polygons_W(scene, h), strict=True):
        lowest = float(poly[:, 1].min())
        if lowest < -tol:
            return f"the {name} enters the support (lowest y = {lowest!r})"
        depth = geo.penetration_depth(poly, obj)
        if depth > tol:
            return f"the {name} overlaps the object by {depth!r}"
    return None
