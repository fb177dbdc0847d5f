"""Gymnasium environments of grasp_env: one id per set-up people train on.

* ``FrictionlessGrasp-v0``: the paper's task (section 4, Fig. 13): scene ``fig13``, the
  palm fixed where the scene puts it, two finger actions (the env's defaults).
* ``FrictionlessGraspRandomShapes-v0``: a new random convex polygon at every reset (default
  ranges) in fig13's hand set-up, the hand starting where the scene puts it, palm and
  fingers under control (five actions).
* ``FrictionlessGraspLift-v0``: the same random shapes, the hand starting at the planner's
  first pre-liftoff placement for each (``start="placement"``: palm pose and finger closing
  fitted to the object, so that a grasp is within reach from the start), with the
  observation's ``hand_features`` (fingertips, hand-object distances, contact positions).

All use the same class with the env's default reward weights and a time limit of
:data:`MAX_EPISODE_STEPS` steps (``time_limit``, the env's own); ``gymnasium.make`` keyword
arguments override the registered ones. :func:`register_envs` registers them with string
entry points, so registering imports neither the environment module nor pygame. Importing
this package (which ``import grasp_env`` does) calls it: ``gymnasium.make("grasp_env:
FrictionlessGrasp-v0")`` and spawned vector-env workers rely on that.

``gymnasium.make`` returns the env itself, with no wrapper: it enforces its own call order
(``step`` and ``render`` before ``reset`` raise), truncates its own episodes and refuses bad
input without changing anything, so nothing outside it needs restoring after a refused call
(gymnasium's ``TimeLimit`` restarts its count when a reset is refused, and its passive
checker breaks every later step after a refused first one; ``disable_env_checker=False``
and ``max_episode_steps`` given to ``gymnasium.make`` add them back, on the caller's terms).
``gymnasium.make_vec(env_id, num_envs=N)`` makes the batched env of the same id
(:class:`grasp_env.envs.vector.FrictionlessGraspVectorEnv`; ``vectorization_mode="sync"``
or ``"async"`` gives gymnasium's vector envs of single envs instead).
"""

from __future__ import annotations

from types import MappingProxyType

#: Id of the paper's set-up, entry point and default episode length of every id.
ENV_ID = "FrictionlessGrasp-v0"
ENTRY_POINT = "grasp_env.envs.frictionless_grasp:FrictionlessGraspEnv"
VECTOR_ENTRY_POINT = "grasp_env.envs.vector:FrictionlessGraspVectorEnv"
MAX_EPISODE_STEPS = 200
#: Id of the randomized-shapes set-up with palm control.
RANDOM_SHAPES_ENV_ID = "FrictionlessGraspRandomShapes-v0"
#: Id of the lifting task: random shapes from the planner's pre-liftoff placement.
LIFT_ENV_ID = "FrictionlessGraspLift-v0"
#: The registered ids and their ``gymnasium.make`` keyword arguments (read-only).
ENV_KWARGS = MappingProxyType(
    {
        ENV_ID: MappingProxyType({"time_limit": MAX_EPISODE_STEPS}),
        RANDOM_SHAPES_ENV_ID: MappingProxyType(
            {
                "scene": "fig13",
                "shape_randomizer": True,
                "palm_control": True,
                "start": "scene",
                "time_limit": MAX_EPISODE_STEPS,
            }
        ),
        LIFT_ENV_ID: MappingProxyType(
            {
                "scene": "fig13",
                "shape_randomizer": True,
                "palm_control": True,
                "start": "placement",
                "hand_features": True,
                "time_limit": MAX_EPISODE_STEPS,
            }
        ),
    }
)
#: The spec's ``reward_threshold`` (every id): with the default reward weights, an episode
#: return of at least this means the episode reached a grasp. It is the form-closure bonus
#: (``reward_form_closure_weight``, 10), paid once, at the first step in form closure with the
#: object off the support. Without the bonus a return stays well below 10: the grip term is
#: paid only in form closure off the support, and the lift shaping sums to about
#: ``gamma * Phi`` of the last state, under 5 (the object's centre stays within 5 palm widths
#: above its start: palm height at most 3 w, reach 2 w). A drop costs 10 and cancels the bonus
#: of a grasp that is soon lost. A held grasp also earns up to 0.1 a step of grip term: the
#: scripted planner's fig13 episode returns about 24.5, random actions about 0.
REWARD_THRESHOLD = 10.0


def register_envs() -> None:
    """Register every id of :data:`ENV_KWARGS` with gymnasium (idempotent)."""
    from gymnasium.envs.registration import register, registry

    for env_id, kwargs in ENV_KWARGS.items():
        if env_id not in registry:
            register(
                id=env_id,
                entry_point=ENTRY_POINT,
                vector_entry_point=VECTOR_ENTRY_POINT,
                reward_threshold=REWARD_THRESHOLD,
                order_enforce=False,
                disable_env_checker=True,
                kwargs=dict(kwargs),
            )


register_envs()

__all__ = [
    "ENTRY_POINT",
    "ENV_ID",
    "ENV_KWARGS",
    "LIFT_ENV_ID",
    "MAX_EPISODE_STEPS",
    "RANDOM_SHAPES_ENV_ID",
    "REWARD_THRESHOLD",
    "VECTOR_ENTRY_POINT",
    "register_envs",
]
