"""Gymnasium environments of grasp_env: ``FrictionlessGrasp-v0``.

:func:`register_envs` registers them with a string entry point, so registering imports
neither the environment module nor pygame. Importing this package (which ``import grasp_env``
does) calls it: ``gymnasium.make("grasp_env:FrictionlessGrasp-v0")`` and spawned vector-env
workers rely on that. ``gymnasium.make`` puts :class:`RestoreOnError
<grasp_env.envs.frictionless_grasp.RestoreOnError>` outside its standard wrappers, so that a
refused ``reset`` or ``step`` leaves them as they were.
"""

from __future__ import annotations

#: Id, entry point and default episode length of the registered environment.
ENV_ID = "FrictionlessGrasp-v0"
ENTRY_POINT = "grasp_env.envs.frictionless_grasp:FrictionlessGraspEnv"
MAX_EPISODE_STEPS = 200
#: The spec's ``reward_threshold``: with the default reward weights, an episode return of at
#: least this means the episode reached a grasp. It is the form-closure bonus
#: (``reward_form_closure_weight``, 10), paid once, at the first step in form closure with the
#: object off the support. Without the bonus a return stays well below 10: the grip term is
#: paid only in form closure off the support, and the lift shaping sums to about
#: ``gamma * Phi`` of the last state, under 5 (the object's centre stays within 5 palm widths
#: above its start: palm height at most 3 w, reach 2 w). A drop costs 10 and cancels the bonus
#: of a grasp that is soon lost. A held grasp also earns up to 0.1 a step of grip term: the
#: scripted planner's fig13 episode returns about 24.5, random actions about 0.
REWARD_THRESHOLD = 10.0
#: The wrapper ``gymnasium.make`` adds outside ``PassiveEnvChecker``, ``OrderEnforcing`` and
#: ``TimeLimit``.
WRAPPER_ENTRY_POINT = "grasp_env.envs.frictionless_grasp:RestoreOnError"


def register_envs() -> None:
    """Register ``FrictionlessGrasp-v0`` with gymnasium (idempotent)."""
    from gymnasium.envs.registration import WrapperSpec, register, registry

    if ENV_ID not in registry:
        register(
            id=ENV_ID,
            entry_point=ENTRY_POINT,
            max_episode_steps=MAX_EPISODE_STEPS,
            reward_threshold=REWARD_THRESHOLD,
            additional_wrappers=(WrapperSpec("RestoreOnError", WRAPPER_ENTRY_POINT, {}),),
        )


register_envs()

__all__ = [
    "ENTRY_POINT",
    "ENV_ID",
    "MAX_EPISODE_STEPS",
    "REWARD_THRESHOLD",
    "WRAPPER_ENTRY_POINT",
    "register_envs",
]
