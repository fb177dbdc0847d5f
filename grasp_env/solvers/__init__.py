"""The small linear programs and linear algebra of the project, each with its reference:

* :mod:`~grasp_env.solvers.lp`: the reference path through scipy's HiGHS;
* :mod:`~grasp_env.solvers.velocity_lp` (compiled) and :mod:`~grasp_env.solvers.fastlp` (its
  Python front end): the exact motion LP and form-closure test by basis enumeration;
* :mod:`~grasp_env.solvers.motion_lp`: the motion LP by either path, checked against each
  other;
* :mod:`~grasp_env.solvers.simplex` (compiled): the grip objective's LP;
* :mod:`~grasp_env.solvers.least_norm` (compiled) and :mod:`~grasp_env.solvers.qp` (its
  reference): least-norm twists;
* :mod:`~grasp_env.solvers.dense` (compiled): 3x3 and 4x4 solves, NNLS and ranks written out,
  so that no result depends on the machine's BLAS.
"""
