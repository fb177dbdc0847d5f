"""What ``FrictionlessGrasp-v0`` shares with any task on the simulator: the episode's
simulator and compiled model (an :class:`grasp_env.envs.episode.Episode`), the action space
and the action's hand target, :meth:`GraspEnvBase.simulate_action`, the read-only accessors,
rendering, and pickling and copying. The task (:mod:`grasp_env.envs.frictionless_grasp`)
adds its documentation, observation, reward, episode end, starts, resets and step.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from grasp_env.arguments import integer
from grasp_env.core.scene import Scene
from grasp_env.core.state import State
from grasp_env.envs.checks import RenderModes, action_values, one_of
from grasp_env.envs.episode import Episode, episode_constants, state_arrays
from grasp_env.kernel import step as kernel
from grasp_env.render import Renderer
from grasp_env.simulator import Simulator, own_state

#: Largest ``render_width`` and ``render_height``, in pixels.
MAX_RENDER_SIZE = 16384


class GraspEnvBase(gym.Env):
    """A Gymnasium env whose episodes run on the simulator and the env's compiled step
    (:mod:`grasp_env.kernel.step`).

    An action of ``action_size`` entries in [-1, 1] asks for a hand target: the fingers close
    by ``max_finger_step`` per unit, the palm (with palm control) moves by ``max_palm_step``
    (palm widths, palm widths, rad) within its workspace (:func:`grasp_env.kernel.step.
    target_of`). A task sets ``max_finger_step`` and ``max_palm_step``, the kernel's
    ``_settings`` and the observation bounds ``_obs_low``/``_obs_high`` before its first
    reset, and starts its episodes with :meth:`_new_episode`.

    Args:
        action_size: entries of an action (2: the fingers; 5: the palm too).
        render_mode: None, ``"rgb_array"`` or ``"human"``.
        render_width, render_height: frame size in pixels (16 to :data:`MAX_RENDER_SIZE`).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": RenderModes(["human", "rgb_array"]),
        "render_fps": 30,
    }
    max_finger_step: float
    max_palm_step: np.ndarray
    #: Coulomb friction at every contact that stops a step it can jam (0: none).
    friction: float = 0.0
    _settings: np.ndarray
    _obs_low: np.ndarray
    _obs_high: np.ndarray

    def __init__(
        self, *, action_size: int, render_mode: str | None, render_width: int, render_height: int
    ) -> None:
        if render_mode is not None:
            one_of(render_mode, "render_mode", self.metadata["render_modes"], "None or ")
        self.render_mode = render_mode
        self.render_size = (
            integer(render_width, "render_width", 16, most=MAX_RENDER_SIZE),
            integer(render_height, "render_height", 16, most=MAX_RENDER_SIZE),
        )
        self.action_space = spaces.Box(-1.0, 1.0, (action_size,), np.float32)
        self._renderer: Renderer | None = None
        self._episode: Episode | None = None
        #: The first episode of each start the task keeps (by its key), copied at a reset
        #: from it instead of analysed again.
        self._episodes: dict[Any, Episode] = {}

    # ------------------------------------------------------------------ public accessors
    @property
    def state(self) -> State | None:
        """The current simulator state (immutable; None before the first :meth:`reset`).

        Holds the hand configuration, the object's pose, the contacts with their forces and the
        last move's events (:class:`grasp_env.State`). Read-only: the env moves on only through
        :meth:`reset` and :meth:`step`.
        """
        return None if self._episode is None else self._episode.state

    @property
    def simulator(self) -> Simulator | None:
        """The :class:`grasp_env.Simulator` of the current episode (None before the first
        :meth:`reset`). A model for planners: its ``move_hand`` and ``settle`` return new
        states and leave the env as it is."""
        return None if self._episode is None else self._episode.sim

    @property
    def scene(self) -> Scene | None:
        """The :class:`grasp_env.Scene` of the current episode (None before the first
        :meth:`reset`): one of :attr:`scenes`, the ``options["scene"]`` of the reset, or the
        random shape drawn with ``shape_randomizer``; with ``uncertainty``, perturbed."""
        return None if self._episode is None else self._episode.state.scene

    @property
    def nominal_scene(self) -> Scene | None:
        """The :class:`grasp_env.Scene` the policy and the planner are told (None before the
        first :meth:`reset`): :attr:`scene` itself, or with ``uncertainty`` the nominal scene
        whose perturbation :attr:`scene` simulates. The observation's shape features are
        its object's."""
        return None if self._episode is None else self._episode.nominal.scene

    # ------------------------------------------------------------------ actions and episodes
    def _check_action(self, action: Any) -> list[float]:
        """The action as Python floats clipped into [-1, 1]; refused (``ValueError``) unless it
        is finite real numbers of the action space's shape."""
        return action_values(action, self.action_space.shape[0])

    def _new_episode(
        self, sim: Simulator, state: State, nominal: Simulator | None = None, key: Any = None
    ) -> Episode:
        """The episode of ``sim`` starting at ``state``, observed with the shape of
        ``nominal``'s object (default ``sim``'s): its constants (the action's steps and the
        palm workspace among them) and analysis; changes nothing of the env but the cache of
        first episodes. ``key``: the start's, where the task keeps it (every episode from it
        starts the same, so the first is kept and copied)."""
        if key is not None and key in self._episodes:
            return self._episodes[key].fresh()
        consts = episode_constants(
            state.scene, state, self.max_finger_step, self.max_palm_step, sim.model.rho
        )
        episode = Episode(sim, state, consts, self._settings, len(self._obs_low), nominal)
        if key is not None:
            self._episodes[key] = episode.fresh()
        return episode

    def simulate_action(self, state: State, action: Any) -> State:
        """The state ``action`` leads to from ``state``, without changing the env.

        Computed exactly as :meth:`step` computes it (same action checks and clipping, same
        simulator call), so that what a planner acting through the env plans is what the env
        then does, to the last bit: for the env's current state,
        ``simulate_action(env.state, a)`` is the state ``step(a)`` moves to. Use it with
        :attr:`state` (e.g. the scripted policy's exploratory lifting searches on it).

        Args:
            state: a state of the current episode's scene (:attr:`state` or one returned by
                this method).
            action: as for :meth:`step`: real numbers of the action space's shape, clipped
                into [-1, 1].

        Returns:
            The new state (the env's own state is unchanged); with ``friction``, a step it
            jams returns ``state`` marked ``jammed``, with no events.

        Raises:
            ValueError: a bad action (as :meth:`step`).
            TypeError: ``state`` is not a :class:`grasp_env.State`.
            ValueError: ``state`` is of another scene than the current episode's, or a state
                built by hand that :meth:`grasp_env.Simulator.check_state` refuses.
            RuntimeError: called before the first :meth:`reset`.
            SimulationError, SolverError: where :meth:`step` would end the episode with
                ``info["sim_error"]``.
        """
        a = self._check_action(action)
        if self._episode is None:
            raise RuntimeError("call reset() before simulate_action()")
        sim = self._episode.sim
        own_state(state, sim.scene)
        if state._by_hand:  # a simulator's state needs no check
            sim.check_state(state)
        if self.friction > 0.0 and self._episode.friction_jams(
            state_arrays(state), np.array(a), self._settings, self.friction
        ):
            return replace(state, jammed=True, hand_blocked=False, events=())
        return self._episode.simulate(state, np.array(a), self._settings)

    # ------------------------------------------------------------------ rendering
    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; make the env with "
                'render_mode="rgb_array" or "human"'
            )
            return None
        if self._episode is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            self._renderer = Renderer(*self.render_size, fps=self.metadata["render_fps"])
        frame = self._renderer.draw(self._episode.state, self._caption())
        if self.render_mode == "human":
            self._renderer.show(frame)
            return None
        return frame

    def _caption(self) -> str:
        episode = self._episode
        scene, an = episode.state.scene, episode.an
        text = f"{scene.name} | step {int(episode.ep[kernel.E_STEPS])}"
        if an[kernel.A_CLOSURE]:
            text += f" | form closure | y* = {an[kernel.A_GRIP] / scene.object_weight:.2f} W"
        else:
            text += " | no form closure"
        return text

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ pickling and copying
    def __getstate__(self) -> dict:
        d = self.__dict__.copy()
        d["_renderer"] = None  # pygame objects do not pickle; a copy renders afresh
        return d


__all__ = ["MAX_RENDER_SIZE", "GraspEnvBase"]
