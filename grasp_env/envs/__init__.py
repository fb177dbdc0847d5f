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
            additional_wrappers=(WrapperSpec("RestoreOnError", WRAPPER_ENTRY_POINT, {}),),
        )


register_envs()

__all__ = ["ENTRY_POINT", "ENV_ID", "MAX_EPISODE_STEPS", "WRAPPER_ENTRY_POINT", "register_envs"]
