"""grasp_env: frictionless enveloping grasping in the plane (Trinkle, Abel & Paul, IJRR 1988).

The public API (docs/conventions.md, "Public API"): :func:`load_scene`, :class:`Simulator`,
the analysis functions (:func:`is_form_closure`, :func:`is_force_closure`,
:func:`grip_objective`, :func:`tippability_regions`, :func:`object_width`,
:func:`critical_friction`, :func:`jams_with_friction`) and the Gymnasium
environment ``FrictionlessGrasp-v0``.
"""

from grasp_env import envs as _envs  # noqa: F401  (registers FrictionlessGrasp-v0)
from grasp_env.core.scene import Scene
from grasp_env.core.scene_loading import bundled_scenes, load_scene
from grasp_env.core.state import Contact, Event, State
from grasp_env.errors import ComputationError, SceneError, SolverError
from grasp_env.mechanics.closure import (
    escape_direction,
    grip_objective,
    is_force_closure,
    is_form_closure,
)
from grasp_env.mechanics.friction import critical_friction, jams_with_friction
from grasp_env.mechanics.tippability import tippability_regions
from grasp_env.mechanics.width import object_width
from grasp_env.simulator import SimulationError, Simulator

__all__ = [
    "ComputationError",
    "Contact",
    "Event",
    "Scene",
    "SceneError",
    "SimulationError",
    "Simulator",
    "SolverError",
    "State",
    "bundled_scenes",
    "critical_friction",
    "escape_direction",
    "grip_objective",
    "is_force_closure",
    "is_form_closure",
    "jams_with_friction",
    "load_scene",
    "object_width",
    "tippability_regions",
]

__version__ = "0.1.0"
