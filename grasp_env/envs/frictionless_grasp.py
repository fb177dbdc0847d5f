"""``FrictionlessGrasp-v0``: pick a convex polygon up off a flat support without friction.

The task on :class:`grasp_env.envs.base.GraspEnvBase` (the simulator, actions,
``simulate_action``, accessors, rendering), as Gymnasium's MuJoCo tasks sit on ``MujocoEnv``:
its arguments, starts and resets, step, info, and in the class docstring its documentation in
Gymnasium's style (spaces, starts, rewards, episode end, arguments), about half of this
module. Its observation layout is in :mod:`grasp_env.kernel.observation`, its reward and
episode end in :mod:`grasp_env.kernel.step`, the checks of its arguments in
:mod:`grasp_env.envs.checks`.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from grasp_env.arguments import integer, number, short
from grasp_env.core.scene import Scene
from grasp_env.core.state import State
from grasp_env.envs.base import GraspEnvBase
from grasp_env.envs.checks import (
    env_scene,
    flag,
    numbers,
    one_of,
    option_start,
    placement_problem,
    reset_options,
    shape_problem,
    shape_ranges,
    uncertainty_sds,
)
from grasp_env.envs.episode import REWARD_KEYS, env_settings
from grasp_env.envs.shapes import hand_setup, random_shape_scene
from grasp_env.envs.uncertainty import perturbed_scene
from grasp_env.errors import ComputationError
from grasp_env.kernel import step as kernel
from grasp_env.kernel.observation import observation_bounds
from grasp_env.mechanics.friction import MU_MAX
from grasp_env.planning import centred_placement, first_placement
from grasp_env.simulator import CONTACT_TOL_RANGE, Simulator

#: Largest perturbations of the ``"random"`` start: palm x and y (palm widths), palm angle
#: (rad), finger angles (rad).
RANDOM_PALM_XY, RANDOM_PALM_THETA, RANDOM_FINGER = 0.02, 0.05, 0.1
RANDOM_START_TRIES = 50

_STARTS = ("scene", "preliftoff", "random", "placement")
#: The pre-liftoff placement of each start that has one.
_PLACEMENTS = {"preliftoff": centred_placement, "random": centred_placement,
               "placement": lambda sim: first_placement(sim)[0]}  # fmt: skip
#: The reward's terms, in the order of ``info["reward_<term>"]``.
REWARD_TERMS = kernel.REWARD_TERMS
#: Largest reward weight: a step's reward stays far from the float range.
MAX_REWARD_WEIGHT = 1e6
#: Largest ``shape_pool``: a pool entry is drawn as a 64-bit integer.
MAX_POOL = 2**63
#: Largest ``max_vertices`` (the observation has 3 entries per vertex).
MAX_VERTICES = 1000


class FrictionlessGraspEnv(GraspEnvBase):
    r"""Frictionless enveloping grasping in the plane (Trinkle, Abel & Paul, IJRR 1988).

    ## Description

    A planar hand, a flat palm with two hinged single-link fingers under exact position
    control, has to pick a convex polygon up off a flat support, with gravity and **without
    friction**. The object's motion is quasi-static: for every hand motion it moves so as to
    lower its potential energy as far as the contacts allow (the paper's eqs. 19-24, solved
    by :class:`grasp_env.Simulator`). Without friction a grasp is secure only in **form
    closure**: contacts (fingers, palm) that leave the object no motion at all. The paper's
    strategy is to squeeze the object with the fingers until it slides and tips up off the
    support into the hand (pre-liftoff and lifting), then to adjust the grip. The task is to
    reach form closure with the object off the support, and to hold it with small contact
    forces (a low grip objective ``y*`` of eqs. 31-36).

    Lengths are in palm widths ``w``, forces in object weights ``W``, angles in radians. The
    support is the line ``y = 0``; ``x0`` is the object's x at its scene placement.

    ## Action Space

    ``Box(-1, 1, (2,), float32)`` (``palm_control=False``, the paper's set-up: the palm stays
    where the scene puts it) or ``Box(-1, 1, (5,), float32)`` (``palm_control=True``):

    | index | action | scaled by |
    | --- | --- | --- |
    | 0 | close finger 1 (``q1 += a0 * max_finger_step``; > 0 closes) | ``max_finger_step`` |
    | 1 | close finger 2 (``q2 -= a1 * max_finger_step``; > 0 closes) | ``max_finger_step`` |
    | 2 | palm ``dx`` | ``max_palm_step[0] * w`` |
    | 3 | palm ``dy`` | ``max_palm_step[1] * w`` |
    | 4 | palm ``dtheta`` | ``max_palm_step[2]`` |

    The target hand configuration is the current one plus the scaled action, reached by one
    straight-line hand move of the simulator. Actions outside ``[-1, 1]`` are clipped (they act
    like the bound). An action must be real numbers (ints or floats, Python's or numpy's) of
    the action space's shape: anything else (NaN, inf, an int beyond the float range, a
    string, a complex number, a bool, None, an object array, another shape) raises
    ``ValueError`` naming ``action`` and showing it, and changes nothing. Finger targets beyond
    the joint limits are clipped there; palm targets are clipped into the workspace
    ``|x_p - x0| <= 2 w``, ``0 <= y_p <= 3 w``, ``|theta_p| <= pi/2``. The hand stops short
    when the object jams it or when it would enter the support.

    ## Observation Space

    ``Box(low, high, (24 + 3 N,), float32)`` with ``N = max_vertices`` (60 for the default
    12), and 12 more entries with ``hand_features=True`` (72). Every entry is clipped into its
    bounds.

    | index | observation | min | max |
    | --- | --- | --- | --- |
    | 0 | palm x relative to x0 (``(x_p - x0) / w``) | -2 | 2 |
    | 1 | palm y (``y_p / w``) | 0 | 3 |
    | 2 | palm angle ``theta_p`` | -pi/2 | pi/2 |
    | 3 | finger 1 angle ``q1`` | -pi | pi |
    | 4 | finger 2 angle ``q2`` | -pi | pi |
    | 5 | object centre x relative to x0 (world, ``/ w``) | -4 | 4 |
    | 6 | object centre y (world, ``/ w``) | 0 | 5 |
    | 7 | sin of the object angle (world) | -1 | 1 |
    | 8 | cos of the object angle (world) | -1 | 1 |
    | 9 | object centre x in the palm frame (``/ w``) | -2 | 2 |
    | 10 | object centre y in the palm frame (``/ w``) | -2 | 2 |
    | 11 | sin of the object angle in the palm frame | -1 | 1 |
    | 12 | cos of the object angle in the palm frame | -1 | 1 |
    | 13 .. 12+2N | object vertices ``(x, y) / w`` in the object frame, zero-padded | -2 | 2 |
    | 13+2N .. 12+3N | vertex mask (1 for a real vertex, 0 for padding) | 0 | 1 |
    | 13+3N + 2k | contact count on body k (support, palm, finger 1, finger 2) | 0 | 8 |
    | 14+3N + 2k | total contact force on body k ``/ W`` | 0 | 10 |
    | 21+3N | form closure (1) or not (0) | 0 | 1 |
    | 22+3N | grip objective ``y* / W`` in form closure, else ``y_max`` = 10 | 0 | 10 |
    | 23+3N | object centre height above its start (``/ w``) | -1 | 5 |
    | 24+3N .. 26+3N | contact position on the palm, finger 1, finger 2 (a) | -1 | 1 |
    | 27+3N .. 30+3N | fingertip 1 ``(x, y)``, fingertip 2 ``(x, y)``, palm frame (a) | -2 | 2 |
    | 31+3N .. 35+3N | distance of palm, fingers 1, 2, fingertips 1, 2 from the object (a) | 0 | 2 |

    (a) With ``hand_features=True`` only, lengths ``/ w``. A contact position is the mean x
    of the body's contact points in its own frame over its length (palm: from its centre;
    finger: from its joint), 0 where the body has no contact; distances are Euclidean
    between the polygons (0 in contact).

    The contact forces are the simulator's: the least total force holding the object once the
    hand stops (a position-controlled hand adds no preload).

    ## Rewards

    The reward is the sum of six terms, each reported in ``info`` as ``reward_<name>``:

    * ``form_closure``: ``reward_form_closure_weight`` (10) once per episode, at the first
      step in form closure with the object off the support (``info["is_success"]``).
    * ``hold``: ``reward_hold_weight`` (0) at every step in form closure with the object off
      the support: the return counts the steps the grasp holds, as success at the episode's
      end asks.
    * ``grip``: at every step in form closure with the object off the support,
      ``reward_grip_weight * (1 - min(y* / W, y_max) / y_max)`` with ``y_max = 10``: up to
      ``reward_grip_weight`` (0.1) for a grip needing little force. (Form closure with the
      object still on the support is not a grasp and earns nothing.)
    * ``lift``: potential-based shaping ``gamma * Phi(s') - Phi(s)`` with ``Phi =
      reward_lift_weight * (object centre height above its start) / w`` (weight 1, ``gamma``
      0.99); ``Phi = 0`` at a terminal state, so shaping leaves the optimal policy unchanged.
    * ``drop``: ``-reward_drop_weight`` (10) on a drop.
    * ``ctrl``: ``-reward_ctrl_weight * |a|^2`` on the clipped action (weight 0 by default).

    The registered spec's ``reward_threshold`` is 10, the form-closure bonus: with the default
    weights a return of at least 10 means the episode reached a grasp (the other terms stay
    well below 10 without one; see ``grasp_env.envs.REWARD_THRESHOLD``).

    ## Starting State

    The object rests at its scene placement. The hand starts (``start`` kwarg)

    * ``"scene"``: at the scene's hand configuration (the paper's set-up in ``fig13``);
    * ``"preliftoff"``: the planner's centred pre-liftoff placement
      (:func:`grasp_env.planning.centred_placement`): palm centred over the object, parallel
      to the support, just high enough that the longer finger cannot touch it, fingers
      closed at equal rates (by the simulator, in steps of 0.1 rad, the first touch located
      exactly) until each finger touches the object or the fingers jam;
    * ``"random"``: the ``"preliftoff"`` configuration perturbed uniformly by up to
      ``0.02 w`` in palm x and y, 0.05 rad in palm angle and 0.1 rad in each finger angle,
      redrawn until the hand is clear of the object and the support;
    * ``"placement"``: the first pre-liftoff placement the planner tries for the object
      (:func:`grasp_env.planning.first_placement`): palm pose (tilt included) and finger
      closing fitted to it so that the first finger contacts lie where squeezing tips the
      object toward the palm (its tippability regions), each finger closed to its first
      touch; the centred placement where the object has none. A grasp is then within reach
      of the fingers, with no approach to learn.

    With ``shape_randomizer`` the object is a new random convex polygon at every reset, in
    the base scene's hand set-up, its size in palm widths and its mass in ``w**2`` at every
    palm width: a base scene scaled by ``k`` draws, for the same seed, the same shape scaled
    by ``k``, so that the episode's observations and rewards are those of the unscaled scene.
    ``reset(options=...)`` accepts ``{"scene": ..., "palm": (x, y, theta), "fingers": (q1,
    q2), "object_pose": (x, y, theta)}`` (world units): that scene (no randomizer), that hand
    configuration and the object at that pose (missing parts from the scene), settled: an
    object the hand does not hold falls to rest (a start anywhere along a recorded
    trajectory, as a curriculum draws them). A bad option (unknown key, a value that is not
    real numbers as for actions, a bad scene, a hand or the object's centre outside the palm
    workspace, fingers outside their joint limits, bodies overlapping each other or the
    support) or ``seed`` raises ``ValueError`` naming it. A refused reset
    changes nothing: the episode in progress, if any, continues as if the call had not
    happened (same state, same random generator, same step count).

    With ``shape_pool=K`` the random shapes come from a pool of ``K``, each drawn as without
    a pool from a generator seeded by its place in the pool alone, with its start state, and
    made once, the first time a reset draws it: a reset draws a place (uniformly, from the
    env's generator) instead of a new shape. An episode's shape is distributed as without a
    pool; across episodes, shapes recur. Resets cost about a step once the pool is made (the
    ``"placement"`` start takes the planner about 13 ms a shape). Training uses it; the
    evaluation draws fresh shapes.

    ## Episode End

    * Termination: a **drop** (the object lands back on the support after having left it in
      this episode, or its centre leaves the reach box ``|x|, |y| <= 2 w`` about the palm, in
      the palm frame; ``info["dropped"]``), or a failure of the simulator or of the
      analysis' LPs (``info["sim_error"]`` holds the message; the state is left unchanged).
    * With ``friction=mu > 0``, a step whose hand motion Coulomb friction ``mu`` at every
      contact could resist (:func:`grasp_env.critical_friction` of the state and the step's
      hand motion is at most ``mu``: the contacts can hold the object at rest against it)
      is a **friction jam**: the hand stays where it is, ``info["jammed"]`` and
      ``info["friction_jam"]`` are True, and the episode goes on, as after a jam without
      friction. The test is made at the state each step starts from; within a step the
      motion is the frictionless simulator's (docs/friction.md).
    * Truncation: after ``time_limit`` steps (200 for the registered ids), the env's own
      count, which a refused call leaves as it was. (``gymnasium.make(..., max_episode_steps=
      N)`` adds gymnasium's ``TimeLimit`` on top, whose count restarts at a refused reset.)

    ``info`` holds, at reset and every step: ``object_pose``, ``palm_pose``,
    ``finger_angles`` (np arrays), ``contacts`` (list of dicts: body, kind, point, normal,
    force), ``form_closure``, ``grip_force`` (a float: ``y*`` in form closure, ``inf``
    otherwise, and also when the joint torque limits admit no grip; ``math.isfinite`` tells a
    held grasp, and any ``grip_force < limit`` test is False without one),
    ``jammed``, ``hand_blocked``, ``dropped``, ``events`` (the simulator's event kinds),
    ``is_success`` (form closure with the object off the support) and the reward terms
    (zero at reset); with ``always_compute_grip=True`` also ``grip_objective`` (``y*`` of any
    state, ``inf`` if infeasible); with ``friction > 0`` also ``friction_jam`` (steps only).

    ## Arguments

    ```python
    gymnasium.make("FrictionlessGrasp-v0", scene="fig13", palm_control=False, start="scene")
    ```

    * ``scene``: a bundled name (:func:`grasp_env.bundled_scenes`), a YAML path, a dict in the
      scene schema, a ``Scene``, or a list of them (one drawn uniformly at every reset).
      Default ``"fig13"``. A string is a path only if it contains a path separator or ends
      in ``.yaml``/``.yml`` (a ``pathlib.Path`` always is); otherwise it must be a bundled
      name, whatever the working directory holds (:func:`grasp_env.load_scene`).
    * ``shape_randomizer``: None, True (default ranges) or a dict of ranges
      ``{"vertices": (3, 8), "size": (0.2, 0.45), "aspect": (1.0, 3.0), "mass": (0.05,
      0.5)}`` (size: the polygon's diameter in palm widths, within [1e-3, 1e3]; mass in
      ``w**2``, the mass of a ``w x w`` square of density 1; aspect in [1, 100]; see
      :func:`grasp_env.envs.shapes.random_shape_scene`). Shapes whose hand set-up puts the
      palm outside the palm workspace are drawn again, like those that overlap the hand.
    * ``palm_control`` (False), ``max_finger_step`` (0.05 rad), ``max_palm_step`` ((0.02,
      0.02, 0.05): palm widths, palm widths, rad).
    * ``start``: ``"scene"`` (default), ``"preliftoff"``, ``"random"`` or ``"placement"``.
    * ``reward_form_closure_weight`` (10), ``reward_hold_weight`` (0), ``reward_grip_weight`` (0.1),
      ``reward_lift_weight`` (1), ``reward_drop_weight`` (10), ``reward_ctrl_weight`` (0),
      ``gamma`` (0.99): see Rewards. Weights lie in [0, ``MAX_REWARD_WEIGHT`` = 1e6].
    * ``contact_tol``: the simulator's contact tolerance, relative to the palm width (1e-9; in
      [1e-11, 1e-2)).
    * ``max_vertices``: observation padding of the object's vertices (12; at most 1000).
    * ``always_compute_grip``: also compute ``y*`` outside form closure (False: skipped).
    * ``hand_features``: append the hand features to the observation (False).
    * ``shape_pool``: draw random shapes from a pool of this many, at most 2**63 (None: a new
      shape at every reset); see Starting State.
    * ``time_limit``: steps after which an episode is truncated (None: never; the registered
      ids: 200).
    * ``friction``: a Coulomb coefficient ``mu`` in [0, 1e6] at every contact that stops a
      step it can jam (0: none, the paper's frictionless task); see Episode End.
    * ``uncertainty``: how inexactly the object is known (0: exactly). ``sigma`` in [0, 1]:
      at every reset the simulated object is the nominal one with each vertex moved by
      normal noise of sd ``sigma`` palm widths (those on the support along it), redrawn up
      to 100 times until strictly convex, resting on the same edge and clear of the hand;
      ``{"vertices": sigma, "mass": rel_sd}`` also scales the mass by ``1 + rel_sd z``. The
      observation's vertex block and hand-object distances show the nominal object; the
      rest is the simulated one's (docs/uncertainty.md).
    * ``render_mode``: None, ``"rgb_array"`` or ``"human"``; ``render_width``,
      ``render_height`` (640, 480; 16 to 16384 pixels).

    ## Model

    Policies that plan (the scripted planner, :class:`agents.scripted.ScriptedPolicy`) read the
    env through public, read-only accessors of the unwrapped env (``env.unwrapped``; ``None``
    before the first reset):

    * :attr:`state`: the current :class:`grasp_env.State` (immutable: hand, object pose,
      contacts and forces, events);
    * :attr:`simulator`: the episode's :class:`grasp_env.Simulator`;
    * :attr:`scene`: the episode's :class:`grasp_env.Scene` (the simulated one);
    * :attr:`nominal_scene`: the scene the policy is told: :attr:`scene` itself, or with
      ``uncertainty`` the nominal scene whose perturbation is simulated.

    ``env.unwrapped.simulate_action(state, action)`` returns the state an action leads to from
    any state, exactly as ``step`` computes it (same action checks and clipping), without
    changing the env: planners that act through the env (the scripted policy's exploratory
    lifting) plan on it.

    ## Version History

    * v0: initial version. ``info["grip_force"]`` is a plain float, ``inf`` outside form
      closure; the spec has ``reward_threshold=10``; bundled scene names always mean the
      bundled scenes. Added since, with defaults that leave the env as it was: the
      ``"placement"`` start, ``hand_features``, ``reward_hold_weight``
      (``info["reward_hold"]``), ``shape_pool``, ``friction`` and ``uncertainty``. The time
      limit of 200 steps is the env's own (``time_limit``) since the batched env
      (``gymnasium.make_vec``) came: episodes end as before, and ``gymnasium.make`` returns
      the env without wrappers.

    Registered ids (``grasp_env.envs.ENV_KWARGS``), all with ``time_limit=200`` and
    ``reward_threshold=10`` with the default reward weights; keyword arguments of
    ``gymnasium.make`` override the registered ones; ``gymnasium.make_vec(env_id,
    num_envs=N)`` makes the batched env of an id (:mod:`grasp_env.envs.vector`):

    * ``FrictionlessGrasp-v0``: the defaults, the paper's set-up (scene ``fig13``, palm fixed,
      two finger actions, ``start="scene"``);
    * ``FrictionlessGraspRandomShapes-v0``: ``scene="fig13", shape_randomizer=True,
      palm_control=True, start="scene"`` (a new random shape at every reset in fig13's hand
      set-up, five actions);
    * ``FrictionlessGraspLift-v0``: the same with ``start="placement", hand_features=True``
      (the hand starts at the planner's first placement for each shape: lift and hold).
    """

    def __init__(
        self,
        scene: Any = "fig13",
        *,
        shape_randomizer: dict | bool | None = None,
        palm_control: bool = False,
        max_finger_step: float = 0.05,
        max_palm_step: tuple[float, float, float] = (0.02, 0.02, 0.05),
        start: str = "scene",
        reward_form_closure_weight: float = 10.0,
        reward_hold_weight: float = 0.0,
        reward_grip_weight: float = 0.1,
        reward_lift_weight: float = 1.0,
        reward_drop_weight: float = 10.0,
        reward_ctrl_weight: float = 0.0,
        gamma: float = 0.99,
        contact_tol: float = 1e-9,
        max_vertices: int = 12,
        always_compute_grip: bool = False,
        hand_features: bool = False,
        shape_pool: int | None = None,
        time_limit: int | None = None,
        friction: float = 0.0,
        uncertainty: float | dict = 0.0,
        render_mode: str | None = None,
        render_width: int = 640,
        render_height: int = 480,
    ) -> None:
        self.time_limit = None if time_limit is None else integer(time_limit, "time_limit", 1)
        self.palm_control = flag(palm_control, "palm_control")
        self.always_compute_grip = flag(always_compute_grip, "always_compute_grip")
        self.hand_features = flag(hand_features, "hand_features")
        self.max_finger_step = number(max_finger_step, "max_finger_step", 0.0, math.pi / 2)
        self.max_palm_step = numbers(max_palm_step, "max_palm_step", 3, 0.0, 1.0)
        self.start = one_of(start, "start", _STARTS)
        weights = (
            reward_form_closure_weight, reward_hold_weight, reward_grip_weight,
            reward_lift_weight, reward_drop_weight, reward_ctrl_weight,
        )  # fmt: skip
        self.reward_weights = {
            name: number(value, f"reward_{name}_weight", 0.0, MAX_REWARD_WEIGHT, lo_open=False)
            for name, value in zip(REWARD_TERMS, weights, strict=True)
        }
        self.gamma = number(gamma, "gamma", 0.0, 1.0)
        self.contact_tol = number(
            contact_tol, "contact_tol", *CONTACT_TOL_RANGE, lo_open=False, hi_open=True
        )
        self.max_vertices = integer(max_vertices, "max_vertices", 3, TypeError, MAX_VERTICES)
        self.friction = number(friction, "friction", 0.0, MU_MAX, lo_open=False)
        self.uncertainty = uncertainty_sds(uncertainty)
        self._uncertain = any(sd > 0.0 for sd in self.uncertainty.values())
        super().__init__(
            action_size=5 if self.palm_control else 2, render_mode=render_mode,
            render_width=render_width, render_height=render_height,
        )  # fmt: skip

        specs = list(scene) if isinstance(scene, list | tuple) else [scene]
        if not specs:
            raise ValueError("scene must be a scene or a non-empty list of scenes, got []")
        self.scenes = [self._load(spec, "scene") for spec in specs]
        self.shape_ranges = shape_ranges(shape_randomizer, self.max_vertices)
        self._shape_args = (self.shape_ranges, self._shape_problem)
        self._perturbation_args = (self.uncertainty, self._shape_problem)
        self.shape_pool = (
            None if shape_pool is None else integer(shape_pool, "shape_pool", 1, most=MAX_POOL)
        )
        if self.shape_pool is not None and self.shape_ranges is None:
            raise ValueError(f"shape_pool={shape_pool!r} needs a shape_randomizer")
        if self.shape_ranges is not None:
            for base in self.scenes:  # fail now, not at a reset, if no shape fits a hand
                random_shape_scene(np.random.default_rng(0), base, *self._shape_args)
        elif self._uncertain:  # or if no perturbation of a scene is valid
            for base in self.scenes:
                perturbed_scene(np.random.default_rng(0), base, *self._perturbation_args)

        #: Simulators and start states of the bundled scenes (by index) and of the shape
        #: pool's entries (by ``(index, entry)``), made once.
        self._sims: dict[Any, Simulator] = {}
        self._starts: dict[Any, tuple[State, str | None]] = {}
        low, high = observation_bounds(self.max_vertices, self.hand_features)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._obs_low, self._obs_high = low, high
        self._settings = env_settings(
            palm_control=self.palm_control, always_compute_grip=self.always_compute_grip,
            hand_features=self.hand_features, gamma=self.gamma, time_limit=self.time_limit,
            max_vertices=self.max_vertices, reward_weights=self.reward_weights,
        )  # fmt: skip

    # ------------------------------------------------------------------ validation
    def _load(self, spec: Any, name: str) -> Scene:
        """:func:`grasp_env.envs.checks.env_scene` with the env's arguments."""
        return env_scene(spec, name, self.max_vertices, self.start, self.contact_tol)

    def _shape_problem(self, scene: Scene) -> str | None:
        """:func:`grasp_env.envs.checks.shape_problem` at the env's contact tolerance."""
        return shape_problem(scene, self.contact_tol)

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode (see Starting State). A refused reset (bad ``seed`` or ``options``,
        or a simulator error settling the hand they give) changes nothing: the episode in
        progress, if any, and the random generator stay as they were."""
        error = self._begin_episode(seed, options)
        info = self._info(dropped=False, step_info=None)
        if error is not None:
            info["sim_error"] = error
        if self.render_mode == "human":
            self.render()
        return self._observation(), info

    def _begin_episode(self, seed: Any, options: dict | None) -> str | None:
        """The episode :meth:`reset` starts, made the env's; returns the simulator's error on
        the way to a pre-liftoff placement, if any. Everything that can fail runs first, and
        the generator goes back to where it was if it fails. (The batched env's autoreset
        calls it alone: it reads the observation and the outcome from the episode.)"""
        opts = reset_options(options, self._load)
        try:
            if isinstance(seed, bool | np.bool_):
                raise gym.error.Error  # seeding would take it for 0 or 1
            if isinstance(seed, np.integer):  # a number like a Python int, as everywhere
                seed = int(seed)
            rng = self.np_random if seed is None else seeding.np_random(seed)[0]
        except gym.error.Error:
            raise ValueError(f"seed must be None or an int >= 0, got {short(seed)}") from None
        drawn_from = rng.bit_generator.state
        try:
            sim, state, error, nominal, key = self._start(rng, opts)
            episode = self._new_episode(sim, state, nominal, key)
        except BaseException:
            rng.bit_generator.state = drawn_from  # the env's own generator draws nothing
            raise
        if seed is not None:
            super().reset(seed=seed)
            self.np_random.bit_generator.state = rng.bit_generator.state  # the draws above
        self._episode = episode
        if self._renderer is not None:
            self._renderer.reset_view()
        return error

    def _start(
        self, rng: np.random.Generator, opts: dict[str, Any]
    ) -> tuple[Simulator, State, str | None, Simulator, Any]:
        """The simulator, start state, pre-liftoff error and nominal simulator of a new
        episode, drawn from ``rng``, and the key of the start where it is one the env keeps
        (a bundled scene's or a pool entry's, unperturbed; else None); changes no episode
        state (it fills only the simulator and start caches). With ``uncertainty`` the
        simulated object is a perturbation of the nominal one, and the start is made on
        it."""
        if "scene" in opts:
            scene = opts["scene"]
            sim, key = Simulator(scene, contact_tol=self.contact_tol), None
        else:
            idx = int(rng.integers(len(self.scenes))) if len(self.scenes) > 1 else 0
            key = idx
            if self.shape_ranges is not None and self.shape_pool is None:
                scene = random_shape_scene(rng, self.scenes[idx], *self._shape_args)
                sim, key = Simulator(scene, contact_tol=self.contact_tol), None
            elif self.shape_ranges is not None:
                key = (idx, int(rng.integers(self.shape_pool)))
            if key is not None and key not in self._sims:
                self._sims[key] = Simulator(self._scene_of(key), contact_tol=self.contact_tol)
            sim = self._sims[key] if key is not None else sim
            scene = sim.scene
        nominal = sim
        if self._uncertain:
            scene = perturbed_scene(rng, nominal.scene, *self._perturbation_args)
            sim, key = Simulator(scene, contact_tol=self.contact_tol), None
        if "palm" in opts or "fingers" in opts or "object_pose" in opts:
            pose, hand = option_start(scene, opts, self.contact_tol)
            return sim, sim.settle(pose, hand), None, nominal, None
        state, error = self._first_state(sim, key)
        if self.start == "random":
            return sim, self._perturb(sim, state, rng), error, nominal, None
        return sim, state, error, nominal, key if key in self._starts else None

    def _scene_of(self, key: Any) -> Scene:
        """The scene of a bundled scene's index, or of the shape pool's entry ``(index,
        entry)``: a random shape drawn from a generator seeded by the entry alone."""
        if not isinstance(key, tuple):
            return self.scenes[key]
        idx, entry = key
        rng = np.random.default_rng([idx, entry])
        return random_shape_scene(rng, self.scenes[idx], *self._shape_args)

    def _first_state(self, sim: Simulator, key: Any) -> tuple[State, str | None]:
        """The start's state before any perturbation (made once per bundled scene or pool
        entry), with the error where the simulator failed on the way to a pre-liftoff
        placement."""
        if key is not None and key in self._starts:
            return self._starts[key]
        if self.start == "scene":
            found = sim.reset(), None
        else:
            found = self._placement(sim)
        if key is not None and found[1] is None:
            self._starts[key] = found
        return found

    def _placement(self, sim: Simulator) -> tuple[State, str | None]:
        """The start's pre-liftoff placement, or the pre-liftoff hand set-up with the error
        where the simulator failed on the way there."""
        scene = sim.scene
        try:
            return _PLACEMENTS[self.start](sim), None
        except ComputationError as exc:
            state = sim.settle(scene.object.start_pose, hand_setup(scene))
            return state, f"pre-liftoff placement stopped: {exc}"

    def _perturb(self, sim: Simulator, state: State, rng: np.random.Generator) -> State:
        scene = sim.scene
        w = scene.palm.width
        xy, th, q = RANDOM_PALM_XY * w, RANDOM_PALM_THETA, RANDOM_FINGER
        scale = np.array([xy, xy, th, q, q])
        lim = scene.joint_limits
        for _ in range(RANDOM_START_TRIES):
            h = state.hand + rng.uniform(-1.0, 1.0, 5) * scale
            h[3:] = np.clip(h[3:], lim[:, 0], lim[:, 1])
            if placement_problem(scene, state.object_pose, h, self.contact_tol) is None:
                try:
                    return sim.settle(state.object_pose, h)
                except ComputationError:
                    continue  # draw another perturbation
        return state

    # ------------------------------------------------------------------ step
    def step(self, action: Any):
        a = self._check_action(action)
        if self._episode is None:
            raise RuntimeError("call reset() before step()")
        episode = self._episode
        arrays = (episode.q, episode.h, episode.keys, episode.rows)
        friction_jam = self.friction > 0.0 and episode.friction_jams(
            arrays, np.array(a), self._settings, self.friction
        )
        if friction_jam:  # the hand stays where it is
            a = [0.0] * len(a)
        obs, info, error = episode.advance(
            np.array(a), self._settings, self._obs_low, self._obs_high
        )
        if self.render_mode == "human":
            self.render()
        reward = float(info[kernel.I_REWARD])
        terminated, truncated = bool(info[kernel.I_TERMINATED]), bool(info[kernel.I_TRUNCATED])
        out = self._info(info[kernel.I_DROPPED], info)
        if self.friction > 0.0:
            out["friction_jam"] = friction_jam
            out["jammed"] = out["jammed"] or friction_jam
        if error is not None:
            out["sim_error"] = error
        return obs, reward, terminated, truncated, out

    # ------------------------------------------------------------------ observation / info
    def _observation(self) -> np.ndarray:
        return self._episode.observation(self._settings, self._obs_low, self._obs_high)

    def _info(self, dropped: bool, step_info: np.ndarray | None) -> dict[str, Any]:
        """The info dict of the current state; ``step_info`` the kernel's of the step that
        led there (None at a reset: the reward terms are zero)."""
        state = self._episode.state
        hand = state.hand.copy()
        info = {
            "object_pose": state.object_pose.copy(),
            "palm_pose": hand[:3],
            "finger_angles": hand[3:],
            "contacts": [c.as_dict() for c in state.contacts],
            "events": [e.kind for e in state.events],
        } | self._outcome(dropped, step_info)
        if self.always_compute_grip:
            info["grip_objective"] = float(self._episode.an[kernel.A_GRIP])
        return info

    def _outcome(self, dropped: bool, step_info: np.ndarray | None) -> dict[str, Any]:
        """The info entries of :meth:`_info` that the batched env batches: the closure, the
        grip, the flags and the reward terms."""
        state, an = self._episode.state, self._episode.an
        closure = bool(an[kernel.A_CLOSURE])
        out = {
            "form_closure": closure,
            "grip_force": float(an[kernel.A_GRIP]) if closure else math.inf,
            "jammed": bool(state.jammed),
            "hand_blocked": bool(state.hand_blocked),
            "dropped": bool(dropped),
            "is_success": bool(an[kernel.A_SUCCESS]),
        }
        for i, key in enumerate(REWARD_KEYS):
            out[key] = 0.0 if step_info is None else float(step_info[kernel.I_TERMS + i])
        return out


__all__ = ["REWARD_TERMS", "FrictionlessGraspEnv"]
