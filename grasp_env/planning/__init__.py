"""The paper's three-phase grasp planner (section 3.2), one module per phase:

* :mod:`~grasp_env.planning.preliftoff`: hand placements from which squeezing tips the
  object toward the palm (the tippability regions, Fig. 4, also about the pivot of a
  holding fingertip that cannot reach the support contact), and
  :mod:`~grasp_env.planning.centred`: the centred placement;
* :mod:`~grasp_env.planning.lifting`: finger increments with the palm fixed until form
  closure off the support;
* :mod:`~grasp_env.planning.grip`: descent of ``y*`` along the four-contact branches;
* :mod:`~grasp_env.planning.regrasp`: exploratory lifting with palm motion, the last resort;
* :mod:`~grasp_env.planning.grasp`: the whole plan (:func:`plan_grasp`);
* :mod:`~grasp_env.planning.approach`: collision-free hand paths to a placement;
* :mod:`~grasp_env.planning.plan`: the plan's record and the questions every phase asks of
  a state.

The planner drives the :class:`~grasp_env.simulator.Simulator` with hand increments and
records every step (:class:`PlanStep`). It assumes exact knowledge of the scene, as the paper
does.
"""

from grasp_env.planning.approach import approach_path
from grasp_env.planning.grasp import EXPLORE_MOVES, explore, first_placement, plan_grasp
from grasp_env.planning.grip import FourContactBranch, adjust_grip, grip_curves
from grasp_env.planning.lifting import lift
from grasp_env.planning.plan import (
    PHASES,
    BranchProbe,
    PhaseResult,
    Plan,
    PlanStep,
    both_fingers_touch,
    finger_gap,
    grasped,
    palm_distance,
    touching_bodies,
    try_move,
)
from grasp_env.planning.preliftoff import (
    centred_hand,
    centred_placement,
    close_until_touch,
    pivot_arm,
    pivot_placements,
    scoop_placement,
    squeeze_tips,
    tipping_placement,
)

__all__ = [
    "EXPLORE_MOVES",
    "PHASES",
    "BranchProbe",
    "FourContactBranch",
    "PhaseResult",
    "Plan",
    "PlanStep",
    "adjust_grip",
    "approach_path",
    "both_fingers_touch",
    "centred_hand",
    "centred_placement",
    "close_until_touch",
    "explore",
    "finger_gap",
    "first_placement",
    "grasped",
    "grip_curves",
    "lift",
    "palm_distance",
    "pivot_arm",
    "pivot_placements",
    "plan_grasp",
    "scoop_placement",
    "squeeze_tips",
    "tipping_placement",
    "touching_bodies",
    "try_move",
]
