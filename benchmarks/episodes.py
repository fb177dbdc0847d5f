"""Seeded random-action episodes of ``FrictionlessGrasp-v0`` shared by the BLAS-variation and
step-time benchmarks.

An episode is named by its suite and seed; the same pair always gives the same env, reset and
actions (on the same arithmetic):

* ``default``: the env's own shape randomizer (``shape_randomizer=True``, fig13 hand);
* ``extreme``: :func:`benchmarks.soak_shapes.random_stress_scene` restricted to ``EXTREME_KINDS``
  (slivers, near-circles, nearly collinear vertices, a bulge of 1e-12..1e-9 on the resting
  edge, on the support or sunk into it), with the soak's aspect (to 1:30) and density
  (1e-3..1e3) ranges;
* ``soak``: the soak's whole stress population (every kind of :data:`soak_shapes.SCENE_KINDS`).

Seed ``s`` starts from ``STARTS[s % 3]`` (all three starts of the env), resets with
``seed=s`` and takes palm-control actions from their own generator (:func:`action_rng`, not
the reset seed), biased to closing the fingers (:func:`benchmarks.soak.random_action`).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

import grasp_env  # noqa: F401  (registers FrictionlessGrasp-v0)
from benchmarks import soak, soak_shapes

SUITES = ("default", "extreme", "soak")
STARTS = ("scene", "preliftoff", "random")
EXTREME_KINDS = ("sliver", "near_circle", "collinear", "bulge", "bulge_sunk")
#: Separate random streams: shapes of a suite, and actions.
_SHAPE_STREAM = {"extreme": 1, "soak": 2}
_ACTION_STREAM = 3
#: Stress scenes drawn before giving up on one whose env accepts the start.
_TRIES = 20


def start_of(seed: int) -> str:
    """The env's ``start`` for episode ``seed``."""
    return STARTS[seed % len(STARTS)]


def make_env(suite: str, seed: int) -> tuple[gym.Env, str]:
    """The env of episode ``(suite, seed)`` (palm control) and its shape's kind."""
    start = start_of(seed)
    if suite == "default":
        env = gym.make(
            "FrictionlessGrasp-v0", palm_control=True, shape_randomizer=True, start=start
        )
        return env, "randomizer"
    if suite not in _SHAPE_STREAM:
        raise ValueError(f"unknown suite {suite!r}; choose from {SUITES}")
    rng = np.random.default_rng([_SHAPE_STREAM[suite], seed])
    kinds = EXTREME_KINDS if suite == "extreme" else soak_shapes.SCENE_KINDS
    last: Exception | None = None
    for _ in range(_TRIES):
        scene = soak_shapes.random_stress_scene(rng, kinds)
        try:
            env = gym.make("FrictionlessGrasp-v0", scene=scene, palm_control=True, start=start)
        except ValueError as exc:  # e.g. no room for the pre-liftoff hand: draw another
            last = exc
            continue
        return env, scene["description"]
    raise RuntimeError(f"{suite} episode {seed}: no shape accepts start={start!r} ({last})")


def action_rng(seed: int) -> np.random.Generator:
    """The action generator of episode ``seed`` (independent of the reset seed's stream)."""
    return np.random.default_rng([_ACTION_STREAM, seed])


def random_action(rng: np.random.Generator) -> np.ndarray:
    """The next action of an episode (the soak's closing-biased palm-control action)."""
    return soak.random_action(rng)


def contact_keys(env: gym.Env) -> list[list[Any]]:
    """The current contacts as sorted ``[body, kind, object_feature, hand_feature]``."""
    state = env.unwrapped.state
    return sorted([c.body, c.kind, c.object_feature, c.hand_feature] for c in state.contacts)
