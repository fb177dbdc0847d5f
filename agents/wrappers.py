"""Training-only wrappers that ``configs/ppo.yml`` names (``env_wrapper``), and the reward
terms they and :mod:`agents.callbacks` read from an info.

The evaluation commands and the policies' own envs see the env's own reward and whole info;
these wrappers shape the reward (:class:`ApproachShaping`), thin the info (:class:`TrainingInfo`)
or choose the starts (:class:`PlannerStarts`) for training only.
"""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np

from grasp_env.arguments import real_array
from grasp_env.errors import ComputationError

#: Prefix of the info keys that hold a reward term (the env's, and shaping terms of wrappers).
REWARD_PREFIX = "reward_"
#: Info keys :class:`TrainingInfo` passes on where a step has them.
PASSED_ON = ("sim_error", "episode")


def reward_terms(info: dict) -> dict[str, float]:
    """The reward terms of a step's info: ``{"reward_<term>": value}``."""
    return {key: value for key, value in info.items() if key.startswith(REWARD_PREFIX)}


class ApproachShaping(gym.Wrapper):
    """Potential-based shaping toward a grasp (training only; the optimal policy is unchanged).

    Adds ``gamma * Phi(s') - Phi(s)`` to the reward, with ``Phi = -approach * |p_P| / w +
    touch * (hand bodies touching the object)``: ``p_P`` is the object's centre in the palm
    frame (observation entries 9-10), so the palm is drawn toward the object and contacts
    are encouraged. ``Phi = 0`` at a terminal state, as for the env's lift term. The term is
    reported as ``info["reward_approach"]``.
    """

    def __init__(self, env: gym.Env, approach: float = 1.0, touch: float = 0.2, gamma=0.99):
        super().__init__(env)
        self.approach, self.touch, self.gamma = float(approach), float(touch), float(gamma)

    def _potential(self, obs: np.ndarray, info: dict) -> float:
        touching = {c["body"] for c in info["contacts"]} - {"support"}
        return -self.approach * float(np.hypot(obs[9], obs[10])) + self.touch * len(touching)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._phi = self._potential(obs, info)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        phi = 0.0 if terminated else self._potential(obs, info)
        shaping = self.gamma * phi - self._phi
        self._phi = phi
        return obs, reward + shaping, terminated, truncated, {**info, "reward_approach": shaping}


def read_starts(path: str | Path, name: str) -> list[dict]:
    """The lifts of a starts file (``python -m agents.planner_starts`` writes them): a list
    of ``{"seed", "scene", "hands", "poses"}``; ValueError naming ``name`` and the file
    where it is missing or holds something else."""
    if not Path(path).is_file():
        raise ValueError(
            f"{name} {str(path)!r} is not a file: write it first with "
            f"python -m agents.planner_starts --out {path}"
        )
    try:
        with open(path, "rb") as f:
            lifts = pickle.load(f)
    except Exception as exc:  # unpickling garbage raises almost anything
        raise ValueError(f"{name} {str(path)!r} is not a starts file: {exc!r}") from None
    if not isinstance(lifts, list) or not all(
        isinstance(t, dict) and {"scene", "hands", "poses"} <= t.keys() for t in lifts
    ):
        raise ValueError(f"{name} {str(path)!r} is not a starts file (a list of lifts)")
    return lifts


class PlannerStarts(gym.Wrapper):
    """Starts along the planner's lifts, a reverse curriculum (training only).

    At a reset without options, with probability ``probability``, the episode starts from a
    state of one of the planner's lifts in ``starts`` (a file ``python -m
    agents.planner_starts`` writes, or a list of them, their lifts pooled): its shape, hand
    and object pose, through the env's reset options. Which lift: one drawn uniformly from
    the pool, or with ``weights`` (one per file) from file ``i`` with probability
    ``weights[i] / sum(weights)``, uniformly among its lifts, so that a file of few lifts
    of one kind (those that leave a placement, say) starts a set share of the episodes.
    Which state: one drawn uniformly from
    the last ``ceil(reach * n)`` of the lift's ``n`` states, ``reach`` growing linearly with
    the env steps this wrapper has seen, from ``first_reach`` to 1 at ``curriculum_steps``:
    first the states next to form closure, then ever earlier ones, back to the placement the
    lift starts from. The other resets are the env's own, and so is a reset whose state the
    simulator cannot settle (counted in ``unsettled``: training goes on). The draws are the
    wrapper's own generator's, seeded by ``reset(seed=...)``.
    """

    def __init__(
        self, env: gym.Env, starts: str | list[str], probability: float = 0.5,
        curriculum_steps: int = 1_000_000, first_reach: float = 0.1,
        weights: list[float] | None = None,
    ) -> None:  # fmt: skip
        super().__init__(env)
        if not 0.0 <= probability <= 1.0:
            raise ValueError(f"probability must be in [0, 1], got {probability!r}")
        if not 0.0 < first_reach <= 1.0:
            raise ValueError(f"first_reach must be in (0, 1], got {first_reach!r}")
        if not curriculum_steps >= 1:
            raise ValueError(f"curriculum_steps must be >= 1, got {curriculum_steps!r}")
        paths = [starts] if isinstance(starts, str | Path) else starts
        if not isinstance(paths, list | tuple) or not all(isinstance(p, str | Path) for p in paths):
            raise ValueError(f"starts must be a file name or a list of them, got {starts!r}")
        self.lifts, self._files = [], []  # the pool, and each file's range in it
        for path in paths:
            lifts = read_starts(path, "starts")
            if not lifts:
                raise ValueError(f"starts {str(path)!r} holds no lift")
            self._files.append((len(self.lifts), len(lifts)))
            self.lifts += lifts
        if not self.lifts:
            raise ValueError(f"starts {starts!r} names no file")
        self.weights = None if weights is None else self._file_weights(weights, len(paths))
        self.probability, self.first_reach = float(probability), float(first_reach)
        self.curriculum_steps = int(curriculum_steps)
        self.steps = self.unsettled = 0
        self._rng = np.random.default_rng()

    @staticmethod
    def _file_weights(weights, files: int) -> np.ndarray:
        """``weights`` as probabilities, one per file; ValueError naming them where they are
        not as many non-negative finite numbers as files, with a positive sum."""
        problem = (
            f"weights must be {files} non-negative numbers with a positive sum, one per "
            f"starts file, got {weights!r}"
        )
        try:
            w = real_array(weights, "weights", (files,))
        except ValueError:
            raise ValueError(problem) from None
        if (w < 0).any() or w.sum() <= 0:
            raise ValueError(problem)
        return w / w.sum()

    @property
    def reach(self) -> float:
        """The fraction of a lift, from its end, that starts are drawn from now."""
        grown = self.steps / self.curriculum_steps
        return min(1.0, self.first_reach + (1.0 - self.first_reach) * grown)

    def start_options(self) -> dict | None:
        """The options of the next reset: a state of a lift, or None (the env's start)."""
        if self._rng.random() >= self.probability:
            return None
        if self.weights is None:
            lift = self.lifts[self._rng.integers(len(self.lifts))]
        else:
            first, count = self._files[self._rng.choice(len(self._files), p=self.weights)]
            lift = self.lifts[first + self._rng.integers(count)]
        n = len(lift["poses"])
        i = self._rng.integers(n - math.ceil(self.reach * n), n)
        hand = lift["hands"][i]
        return {
            "scene": lift["scene"], "palm": hand[:3], "fingers": hand[3:],
            "object_pose": lift["poses"][i],
        }  # fmt: skip

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        if options is not None:
            return self.env.reset(seed=seed, options=options)
        start = self.start_options()
        if start is not None:
            try:
                return self.env.reset(seed=seed, options=start)
            except ComputationError:
                self.unsettled += 1
        return self.env.reset(seed=seed)

    def step(self, action):
        self.steps += 1
        return self.env.step(action)


class TrainingInfo(gym.Wrapper):
    """Keeps of each step's info only what training reads: ``is_success``, the reward terms
    (shaping terms of inner wrappers included), and where present ``sim_error`` and
    ``Monitor``'s ``episode`` (the zoo puts ``env_wrapper`` outside the Monitor; SB3's episode
    statistics and its evaluation count episodes by it). SB3's vector envs copy every info at
    every step (DummyVecEnv deep-copies them, SubprocVecEnv pickles them); the env's whole
    info (poses, contacts with their points and normals, events) made that copy about a fifth
    of PPO's time. Named last in ``env_wrapper``, so that the wrappers inside it still see
    everything."""

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        kept = reward_terms(info)
        kept["is_success"] = info["is_success"]
        for key in PASSED_ON:
            if key in info:
                kept[key] = info[key]
        return obs, reward, terminated, truncated, kept
