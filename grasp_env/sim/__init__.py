"""The quasi-static simulator's compiled kernels.

Kernels (numba, plain arrays, no BLAS) live in modules named for what they compute:
:mod:`~grasp_env.sim.dense` (small linear algebra), :mod:`~grasp_env.sim.placement` (world
geometry and contact gaps), :mod:`~grasp_env.sim.detection` (which vertex-edge pairs touch),
:mod:`~grasp_env.sim.clearance` (vertex-in-body gaps, overlap), :mod:`~grasp_env.sim.pose`
(the object pose on a contact set), :mod:`~grasp_env.sim.consistency` (what a step checks),
:mod:`~grasp_env.sim.least_norm` (least-motion twists) and
:mod:`~grasp_env.sim.velocity_lp` (the velocity and force LPs).
"""
