"""The observation of ``FrictionlessGrasp-v0``: its ranges and layout (the env's docstring
lists every entry) and the geometry it reports, compiled."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from grasp_env.compiled import CACHE
from grasp_env.core import geometry as geo

# Workspace and observation ranges, in palm widths (lengths) and radians, about the object's
# scene position ``x0`` (x) and the support (y).
PALM_X_RANGE = 2.0  #: palm x stays within x0 +- this
PALM_Y_MAX = 3.0  #: palm y stays within [0, this]
PALM_THETA_MAX = 0.5 * math.pi  #: palm angle stays within +- this
REACH = 2.0  #: the object is out of reach when its centre is this far from the palm (palm frame)
OBJECT_X_RANGE = PALM_X_RANGE + REACH
OBJECT_Y_MAX = PALM_Y_MAX + REACH
VERTEX_RANGE = 2.0  #: object vertex coordinates (object frame)
COUNT_MAX = 8.0  #: contacts per body
FORCE_MAX = 10.0  #: total contact force on a body, in object weights
GRIP_MAX = 10.0  #: y* in object weights (``y_max``)
HEIGHT_MIN, HEIGHT_MAX = -1.0, OBJECT_Y_MAX  #: object centre height above its start
TIP_RANGE = 2.0  #: fingertip coordinates in the palm frame (``hand_features``)
DISTANCE_MAX = 2.0  #: hand-object distances (``hand_features``)
HAND_BODIES = ("palm", "finger1", "finger2")

#: Each body's first entry in the observation's contact block (count, then force).
BODY_INDEX = {name: 2 * i for i, name in enumerate(geo.BODY_NAMES)}


#: Entries of the observation's pose block (the hand, the object in the world and in the palm
#: frame), before the object's vertices.
POSE_ENTRIES = 13
#: Entries of the contact block after the vertices and their mask: per body a count and a
#: force, form closure, y*, the object's height, then (``hand_features``) the contact
#: positions on the three hand bodies.
CONTACT_ENTRIES = 2 * len(geo.BODY_NAMES) + 3
POSITION_ENTRIES = len(HAND_BODIES)


def contact_block_at(n: int) -> int:
    """Index of the contact block in an observation with ``n`` padded vertices."""
    return POSE_ENTRIES + 3 * n


def hand_block_at(n: int) -> int:
    """Index of the fingertips and distances (``hand_features``) with ``n`` padded vertices."""
    return contact_block_at(n) + CONTACT_ENTRIES + POSITION_ENTRIES


@njit(cache=CACHE)
def in_palm_frame(hand: np.ndarray, pose: np.ndarray) -> tuple[float, float, float]:
    """Object pose ``(x, y, theta)`` in the palm frame."""
    dx, dy = pose[0] - hand[0], pose[1] - hand[1]
    c, s = math.cos(hand[2]), math.sin(hand[2])
    return (c * dx + s * dy, -s * dx + c * dy, pose[2] - hand[2])


@njit(cache=CACHE)
def contact_positions(
    hand: np.ndarray, points: np.ndarray, bodies: np.ndarray, half: float,
    lengths: np.ndarray, out: np.ndarray,
) -> None:  # fmt: skip
    """Where the object touches each hand body (palm, finger 1, finger 2), into ``out`` (3,):
    the mean x of its contact points (``points`` on ``bodies``) in the body's frame over the
    body's length (``lengths``; palm: from the palm's centre, in palm widths, in [-0.5, 0.5];
    finger: from the joint, in finger lengths, in [0, 1]); 0 where the body has no
    contact."""
    c, s = math.cos(hand[2]), math.sin(hand[2])
    origin_x = (hand[0], hand[0] - c * half, hand[0] + c * half)
    origin_y = (hand[1], hand[1] - s * half, hand[1] + s * half)
    angle = (hand[2], hand[2] + hand[3], hand[2] + hand[4])
    sums = np.zeros(3)
    counts = np.zeros(3)
    for i in range(bodies.shape[0]):
        k = bodies[i] - 1
        if k < 0:
            continue  # the support
        x, y, phi = origin_x[k], origin_y[k], angle[k]
        sums[k] += (math.cos(phi) * (points[i, 0] - x) + math.sin(phi) * (points[i, 1] - y)) / (
            lengths[k]
        )
        counts[k] += 1.0
    for k in range(3):
        out[k] = sums[k] / counts[k] if counts[k] > 0.0 else 0.0


@njit(cache=CACHE)
def finish_observation(
    obs: np.ndarray, hand: np.ndarray, pose: np.ndarray, in_palm: tuple, x0: float, w: float,
    low: np.ndarray, high: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """Write the observation's pose entries (0-12: the hand, the object's pose, the object in
    the palm frame ``in_palm``, lengths in palm widths ``w`` about ``x0``) into ``obs``, and
    return a copy of ``obs`` clipped into ``[low, high]``. Compiled: done by numpy and Python
    floats, this was a tenth of a step."""
    obs[0] = (hand[0] - x0) / w
    obs[1] = hand[1] / w
    obs[2] = hand[2]
    obs[3] = hand[3]
    obs[4] = hand[4]
    obs[5] = (pose[0] - x0) / w
    obs[6] = pose[1] / w
    obs[7] = math.sin(pose[2])
    obs[8] = math.cos(pose[2])
    obs[9] = in_palm[0] / w
    obs[10] = in_palm[1] / w
    obs[11] = math.sin(in_palm[2])
    obs[12] = math.cos(in_palm[2])
    out = np.empty_like(obs)
    for i in range(obs.shape[0]):
        value = obs[i]
        if value < low[i]:
            value = low[i]
        if value > high[i]:
            value = high[i]
        out[i] = value
    return out


def observation_bounds(n: int, hand_features: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of the observation with ``n`` padded vertices (and the
    ``hand_features`` block)."""
    pi = math.pi
    low = [-PALM_X_RANGE, 0.0, -PALM_THETA_MAX, -pi, -pi]
    high = [PALM_X_RANGE, PALM_Y_MAX, PALM_THETA_MAX, pi, pi]
    low += [-OBJECT_X_RANGE, 0.0, -1.0, -1.0, -REACH, -REACH, -1.0, -1.0]
    high += [OBJECT_X_RANGE, OBJECT_Y_MAX, 1.0, 1.0, REACH, REACH, 1.0, 1.0]
    low += [-VERTEX_RANGE] * (2 * n) + [0.0] * n
    high += [VERTEX_RANGE] * (2 * n) + [1.0] * n
    low += [0.0] * (2 * len(geo.BODY_NAMES))
    high += [COUNT_MAX, FORCE_MAX] * len(geo.BODY_NAMES)
    low += [0.0, 0.0, HEIGHT_MIN]
    high += [1.0, GRIP_MAX, HEIGHT_MAX]
    if hand_features:
        low += [-1.0] * len(HAND_BODIES) + [-TIP_RANGE] * 4 + [0.0] * 5
        high += [1.0] * len(HAND_BODIES) + [TIP_RANGE] * 4 + [DISTANCE_MAX] * 5
    return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)
