"""Gymnasium environments of grasp_env: ``FrictionlessGrasp-v0``.

:func:`register_envs` registers them with a string entry point, so registering imports
neither the environment module nor pygame. Importing this package (which ``import grasp_env``
does) calls it: ``gymnasium.make("grasp_env:FrictionlessGrasp-v0")`` and spawned vector-env
workers rely on that.
"""

from __future__ import annotations

#: Id, entry point and default episode length of the registered environment.
ENV_ID = "FrictionlessGrasp-v0"
ENTRY_POINT = "grasp_env.envs.frictionless_grasp:FrictionlessGraspEnv"
MAX_EPISODE_STEPS = 200


def register_envs() -> None:
    """Register ``FrictionlessGrasp-v0`` with gymnasium (idempotent)."""
    from gymnasium.envs.registration import register, registry

    if ENV_ID not in registry:
        register(id=ENV_ID, entry_point=ENTRY_POINT, max_episode_steps=MAX_EPISODE_STEPS)


register_envs()

__all__ = ["ENTRY_POINT", "ENV_ID", "MAX_EPISODE_STEPS", "register_envs"]
