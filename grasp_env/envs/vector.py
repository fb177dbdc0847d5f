"""The batched env: ``num_envs`` episodes of one env id advanced by one compiled call
(:func:`grasp_env.kernel.batch.step_batch`), behind gymnasium's vector API.

``gymnasium.make_vec(env_id, num_envs=N)`` makes it for every registered id (its
``vector_entry_point``). Each sub-env is a :class:`FrictionlessGraspEnv` with the same
arguments, which does its resets and the rare steps the compiled core hands to Python; its
steps run in the batch, on the same compiled functions. So sub-env ``i`` follows, bit for
bit, a single env made with the same arguments, reset with seed ``seed + i`` (``reset(seed=
seed)``; a list gives each its own) and stepped with the same actions; its later episodes
are that single env's after ``reset()`` without a seed.

Autoreset: ``SAME_STEP`` (declared in ``metadata``). A step that ends an episode returns the
next episode's first observation; the last one is in ``infos["final_obs"]`` and the step's
info in ``infos["final_info"]`` (each with its ``"_"``-prefixed mask). Every step's info
arrays are its own; the masks of the entries every sub-env has (all True) are one read-only
array, shared.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numba
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numba import typed

from grasp_env.arguments import integer, short
from grasp_env.envs.checks import batch_actions
from grasp_env.envs.episode import REWARD_KEYS, Episode
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.kernel import step as kernel
from grasp_env.kernel.batch import step_batch
from grasp_env.sim import move

#: Most sub-envs a batched env takes: each takes about 20 kilobytes and a few milliseconds
#: to make, so a count far beyond would run out of memory or time before it is refused.
MAX_ENVS = 65536
#: The info entries of a step, as arrays over the sub-envs, and where the kernel holds them.
INFO_FLAGS = {
    "is_success": kernel.I_SUCCESS,
    "form_closure": kernel.I_CLOSURE,
    "jammed": kernel.I_JAMMED,
    "hand_blocked": kernel.I_BLOCKED,
    "dropped": kernel.I_DROPPED,
}
INFO_VALUES = {"grip_force": kernel.I_GRIP_FORCE} | {
    key: kernel.I_TERMS + i for i, key in enumerate(REWARD_KEYS)
}

#: The kernel's info columns a step returns, in one gather: the reward, then the flags
#: (terminated, truncated and the flags of ``INFO_FLAGS``), then ``INFO_VALUES``.
_COLUMNS = np.array(
    [kernel.I_REWARD, kernel.I_TERMINATED, kernel.I_TRUNCATED, *INFO_FLAGS.values(),
     *INFO_VALUES.values()]
)  # fmt: skip
_FLAGS = slice(1, 3 + len(INFO_FLAGS))  # rows of the flags in the gather
#: The batched entries' keys, in the order of the gather's rows after terminated and truncated.
_ENTRIES = (*INFO_FLAGS, *INFO_VALUES)


class FrictionlessGraspVectorEnv(VectorEnv):
    """``num_envs`` episodes of ``FrictionlessGrasp-v0`` (or another id's arguments) stepped
    together in compiled code.

    Args:
        num_envs: how many sub-envs.
        max_episode_steps: a time limit as ``gymnasium.make`` adds one to a single env: the
            episodes end at the sooner of it and ``time_limit``.
        threads: threads a step runs on (numba's, set for the call; default: as many as the
            machine's cores). The results do not depend on it.
        **kwargs: the single env's arguments (:class:`FrictionlessGraspEnv`).

    ``infos`` hold, for every sub-env, ``is_success``, ``form_closure``, ``grip_force``,
    ``jammed``, ``hand_blocked``, ``dropped``, the reward terms and, with ``friction``,
    ``friction_jam``, as the single env's info does (its poses, contacts and events are not
    batched: :meth:`sub_env` gives what a planner reads), and ``sim_error`` where a step
    failed.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array"],
        "render_fps": 30,
        "autoreset_mode": AutoresetMode.SAME_STEP,
    }

    def __init__(
        self, num_envs: int, *, max_episode_steps: int | None = None, threads: int | None = None,
        **kwargs: Any,
    ) -> None:  # fmt: skip
        self.num_envs = integer(num_envs, "num_envs", 1, most=MAX_ENVS)
        if max_episode_steps is not None:  # as gymnasium's TimeLimit on a single env
            steps = integer(max_episode_steps, "max_episode_steps", 1)
            limit = kwargs.get("time_limit")
            if limit is not None:  # checked as the single env checks it, before comparing
                limit = integer(limit, "time_limit", 1)
            kwargs["time_limit"] = steps if limit is None else min(steps, limit)
        self.threads = (
            numba.config.NUMBA_NUM_THREADS
            if threads is None
            else integer(threads, "threads", 1, most=numba.config.NUMBA_NUM_THREADS)
        )
        self.render_mode = kwargs.get("render_mode")
        if self.render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {self.render_mode!r}")
        self.envs = [FrictionlessGraspEnv(**kwargs) for _ in range(self.num_envs)]
        first = self.envs[0]
        for env in self.envs[1:]:  # one set of simulators, starts and their first episodes
            env._sims, env._starts, env._episodes = first._sims, first._starts, first._episodes
        self.single_action_space = first.action_space
        self.single_observation_space = first.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._settings, self._low, self._high = first._settings, first._obs_low, first._obs_high
        n, size = self.num_envs, len(self._low)
        capacity = 4 * first.max_vertices + 24  # every contact of an object in the hand
        self._consts = np.zeros((n, kernel.CONSTS))
        self._q, self._h = np.zeros((n, 3)), np.zeros((n, 5))
        self._keys = np.zeros((n, capacity, 4), dtype=np.int64)
        self._rows = np.zeros((n, capacity, move.ROW_SIZE))
        self._counts = np.zeros(n, dtype=np.int64)
        self._an = np.zeros((n, kernel.ANALYSIS))
        self._ep = np.zeros((n, kernel.EPISODE))
        self._obs = np.zeros((n, size), dtype=np.float32)
        self._models = None
        self._sources: list = []  # the model each row of _models copies
        self._seen = np.zeros((n, size), dtype=np.float32)
        self._info = np.zeros((n, kernel.INFO))
        self._status = np.zeros(n, dtype=np.int64)
        self._cost = np.zeros(n, dtype=np.int64)  # each row's last step, in cycles
        self._friction = first.friction > 0.0
        self._uncertain = first._uncertain
        self._everyone = np.ones(n, dtype=bool)  # the mask of the entries every sub-env has
        self._everyone.flags.writeable = False  # shared by every info dict: nobody changes it
        self._masks = {f"_{key}": self._everyone for key in _ENTRIES}

    # ------------------------------------------------------------------ episodes and rows
    def _load(self, i: int) -> None:
        """Copy sub-env ``i``'s episode into row ``i`` of the batch (its model's arrays too:
        sub-envs of one scene would share them, and their reference counts, across threads;
        a row whose new episode has the model of its last keeps its copy)."""
        episode = self.envs[i]._episode
        model = episode.sim.compiled_model
        if self._sources[i] is not model:
            self._models[i] = _own_arrays(model)
            self._sources[i] = model
        self._consts[i] = episode.consts
        self._write(i, episode)

    def _write(self, i: int, episode: Episode) -> None:
        m = len(episode.keys)
        if m > self._keys.shape[1]:
            self._grow(m)
        self._q[i], self._h[i], self._counts[i] = episode.q, episode.h, m
        self._keys[i, :m], self._rows[i, :m] = episode.keys, episode.rows
        self._an[i], self._ep[i], self._obs[i] = episode.an, episode.ep, episode.obs

    def _grow(self, m: int) -> None:
        """Room for ``m`` contacts in every row."""
        n = self.num_envs
        keys, rows = np.zeros((n, m, 4), dtype=np.int64), np.zeros((n, m, move.ROW_SIZE))
        keys[:, : self._keys.shape[1]], rows[:, : self._rows.shape[1]] = self._keys, self._rows
        self._keys, self._rows = keys, rows

    def _episode(self, i: int) -> Episode:
        """Sub-env ``i``'s episode as the batch holds it, its state made afresh."""
        episode = self.envs[i]._episode
        m = self._counts[i]
        episode.q, episode.h = self._q[i].copy(), self._h[i].copy()
        episode.keys, episode.rows = self._keys[i, :m].copy(), self._rows[i, :m].copy()
        episode.an, episode.ep = self._an[i].copy(), self._ep[i].copy()
        episode.obs = self._obs[i].copy()
        episode.state = episode.sim.make_state(episode.q, episode.h, episode.keys, episode.rows)
        return episode

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every sub-env: with ``seed`` an int, sub-env ``i`` with ``seed + i``; a list
        gives each its seed (None: its own generator goes on). ``options`` go to every
        sub-env's reset."""
        if seed is None or (isinstance(seed, int | np.integer) and not isinstance(seed, bool)):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        elif isinstance(seed, list | tuple) or (isinstance(seed, np.ndarray) and seed.ndim == 1):
            seeds = list(seed)  # each checked by its sub-env's reset
        else:
            seeds = []
        if len(seeds) != self.num_envs:
            raise ValueError(
                f"seed must be None, an int or a list of {self.num_envs} seeds, got {short(seed)}"
            )
        kept = [
            (env._episode, env._np_random, env._np_random_seed,
             None if env._np_random is None else env._np_random.bit_generator.state)
            for env in self.envs
        ]  # fmt: skip
        observations, infos = [], []
        try:
            for i, env in enumerate(self.envs):
                obs, info = env.reset(seed=seeds[i], options=options)
                observations.append(obs)
                infos.append(info)
        except Exception:  # a refused reset changes nothing: the sub-envs reset go back
            for env, (episode, rng, seed_, bits) in zip(self.envs, kept, strict=True):
                env._episode, env._np_random, env._np_random_seed = episode, rng, seed_
                if rng is not None:
                    rng.bit_generator.state = bits
            raise
        if self._models is None:
            self._sources = [env._episode.sim.compiled_model for env in self.envs]
            self._models = typed.List([_own_arrays(model) for model in self._sources])
        for i in range(self.num_envs):
            self._load(i)
        return np.stack(observations), self._merged(infos)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple:
        """Each sub-env's attribute ``name``, called with the arguments if callable (as
        gymnasium's vector envs do), on its episode as the batch holds it."""
        out = []
        for i in range(self.num_envs):
            value = getattr(self.sub_env(i), name)
            out.append(value(*args, **kwargs) if callable(value) else value)
        return tuple(out)

    def get_attr(self, name: str) -> tuple:
        """Each sub-env's attribute ``name``."""
        return tuple(getattr(self.sub_env(i), name) for i in range(self.num_envs))

    def step(self, actions):
        """One step of every sub-env (see the module docstring for the autoreset)."""
        if self._models is None:
            raise RuntimeError("call reset() before step()")
        actions = batch_actions(actions, (self.num_envs, *self.single_action_space.shape))
        friction_jams = None
        if self._friction:
            friction_jams = self._friction_jams(actions)
            actions[friction_jams] = 0.0  # those hands stay where they are
        if numba.get_num_threads() != self.threads:  # else idle threads would spin-wait
            numba.set_num_threads(self.threads)
        step_batch(
            self._models, self._consts, self._settings, self._q, self._h, self._keys, self._rows,
            self._counts, self._an, self._ep, self._obs, self._low, self._high, actions,
            self._seen, self._info, self._status, self.threads, self._cost,
        )  # fmt: skip
        if self._uncertain:
            self._show_nominal()
        errors = {}
        for i in np.flatnonzero(self._status) if np.count_nonzero(self._status) else ():  # OK: 0
            episode = self._episode(i)  # Python takes the step over, as the single env does
            self._info[i] = 0.0
            self._seen[i], self._info[i], error = episode.advance(
                actions[i], self._settings, self._low, self._high
            )
            if error is not None:
                errors[i] = error
            self._write(i, episode)
        if friction_jams is not None:
            self._info[friction_jams, kernel.I_JAMMED] = 1.0
        return self._results(errors, friction_jams)

    def _show_nominal(self) -> None:
        """The observations of the rows the batch stepped, made again where they show another
        object than the simulated one (as the single env's step makes them)."""
        for i in np.flatnonzero(self._status == kernel.OK):
            episode = self.envs[i]._episode
            if episode.shows_nominal(self._settings):
                self._seen[i] = episode.observe(
                    self._q[i], self._h[i], self._obs[i], self._settings, self._low, self._high
                )

    def _friction_jams(self, actions: np.ndarray) -> np.ndarray:
        """Which sub-envs' actions ask for a hand motion their friction jams, tested as the
        single env tests it (an env with friction only)."""
        jams = np.zeros(self.num_envs, dtype=bool)
        mu = self.envs[0].friction
        for i in range(self.num_envs):
            m = self._counts[i]
            arrays = (self._q[i], self._h[i], self._keys[i, :m], self._rows[i, :m])
            jams[i] = self.envs[i]._episode.friction_jams(arrays, actions[i], self._settings, mu)
        return jams

    def _results(self, errors: dict[int, str], friction_jams: np.ndarray | None):
        block = self._info.T[_COLUMNS]  # one copy: a row per returned entry
        flags = block[_FLAGS] != 0.0  # terminated, truncated, then INFO_FLAGS
        observations, rewards = self._seen.copy(), block[0]
        terminated, truncated, values = flags[0], flags[1], block[_FLAGS.stop :]
        infos = self._step_infos(flags[2:], values, errors, friction_jams)
        if np.count_nonzero(flags[:2]):  # final infos: the step's; the others: the next episodes'
            ended = terminated | truncated
            infos["final_obs"], infos["_final_obs"] = observations.copy(), ended.copy()
            infos["final_info"] = self._step_infos(
                flags[2:].copy(), values.copy(), errors, friction_jams
            )
            infos["_final_info"] = ended.copy()
            for i in np.flatnonzero(ended):  # reset() without its info's poses and contacts
                env = self.envs[i]
                env._begin_episode(None, None)
                self._load(i)
                observations[i] = env._observation()
                outcome = env._outcome(False, None)
                flags[2:, i] = [outcome[key] for key in INFO_FLAGS]
                values[:, i] = [outcome[key] for key in INFO_VALUES]
        return observations, rewards, terminated, truncated, infos

    def _step_infos(
        self, flags: np.ndarray, values: np.ndarray, errors: dict[int, str],
        friction_jams: np.ndarray | None,
    ) -> dict[str, np.ndarray]:  # fmt: skip
        """The batched entries of a step's infos: each flag and value a row of ``flags`` and
        ``values`` (a row per key of ``INFO_FLAGS`` and ``INFO_VALUES``), each mask the
        read-only mask of every sub-env."""
        out = dict(zip(_ENTRIES, (*flags, *values), strict=True)) | self._masks
        if friction_jams is not None:
            out["friction_jam"], out["_friction_jam"] = friction_jams.copy(), self._everyone
        if errors:
            out["sim_error"] = np.array([errors.get(i) for i in range(self.num_envs)], object)
            out["_sim_error"] = np.isin(np.arange(self.num_envs), list(errors))
        return out

    def _merged(self, infos: list[dict]) -> dict[str, np.ndarray]:
        """The reset infos of the sub-envs as arrays (the batched entries of a step)."""
        out = {key: np.array([info[key] for info in infos]) for key in _ENTRIES} | self._masks
        errors = [info.get("sim_error") for info in infos]
        if any(e is not None for e in errors):
            out["sim_error"] = np.array(errors, dtype=object)
            out["_sim_error"] = np.array([e is not None for e in errors])
        return out

    def render(self) -> tuple[np.ndarray, ...] | None:
        """Frames of every sub-env (``render_mode="rgb_array"``), as gymnasium's vector envs
        give them."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode")
            return None
        if self._models is None:
            raise RuntimeError("call reset() before render()")
        return tuple(self.sub_env(i).render() for i in range(self.num_envs))

    def sub_env(self, i: int) -> FrictionlessGraspEnv:
        """Sub-env ``i``, its episode brought up to the batch's: its ``state``, ``simulator``
        and ``simulate_action`` are what a planner reads (read them, do not step it); before
        the first reset, as a single env is before its own (no state yet)."""
        if self.envs[i]._episode is not None:
            self._episode(i)
        return self.envs[i]

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()

    def __repr__(self) -> str:
        return f"FrictionlessGraspVectorEnv(num_envs={self.num_envs}, threads={self.threads})"


def _own_arrays(model):
    """``model`` with copies of its arrays."""
    return model._make([v.copy() if isinstance(v, np.ndarray) else v for v in model])
