"""The quasi-static simulator's compiled core (numba, plain arrays, no BLAS).

A whole hand move is one compiled call, :func:`grasp_env.sim.move.run`, on the
scene's arrays (:class:`grasp_env.sim.model.Model`); the Python
:class:`~grasp_env.simulator.Simulator` wraps it. Its parts live in modules named for what
they compute:

* :mod:`~grasp_env.sim.move`: the entry point, the skips and the contacts of the end state;
* :mod:`~grasp_env.sim.increments`: the increment loop (plan, solve, check, locate, update);
* :mod:`~grasp_env.sim.increment`: one increment on a fixed active set: pose solves, checks
  and event location;
* :mod:`~grasp_env.sim.motion`: the active set and least-motion twist (the LPs);
* :mod:`~grasp_env.sim.fall`: constrained falls;
* :mod:`~grasp_env.sim.equilibrium`: whether contacts hold the object, and the forces;
* :mod:`~grasp_env.sim.hand`: the hand's motion (contact velocities, the support limit);
* :mod:`~grasp_env.sim.contact_sets`, :mod:`~grasp_env.sim.events`: contact sets and event
  codes;
* the geometry kernels, which the analysis (:mod:`grasp_env.mechanics`) uses too:
  :mod:`~grasp_env.sim.placement` (world geometry and contact gaps),
  :mod:`~grasp_env.sim.detection` (which vertex-edge pairs touch),
  :mod:`~grasp_env.sim.clearance` (vertex-in-body gaps, overlap),
  :mod:`~grasp_env.sim.pose` (Newton on a contact set) and :mod:`~grasp_env.sim.consistency`
  (the violations a step checks).

The small linear algebra and the LPs it solves are in :mod:`grasp_env.solvers`; where the
compiled code is cached, in :mod:`grasp_env.compiled`.
"""
