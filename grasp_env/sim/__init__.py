"""The quasi-static simulator and its compiled kernels.

Kernels (numba, plain arrays, no BLAS) live in modules named for what they compute:
:mod:`~grasp_env.sim.dense` (small linear algebra), :mod:`~grasp_env.sim.placement` (world
geometry and contact gaps) and :mod:`~grasp_env.sim.pose` (the object pose on a contact set).
"""
