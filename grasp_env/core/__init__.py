"""The data and geometry everything else builds on: frames and polygons
(:mod:`~grasp_env.core.geometry`), the hand's kinematics (:mod:`~grasp_env.core.kinematics`),
scenes, their schema and loading (:mod:`~grasp_env.core.scene`) and the simulation's
immutable records, :class:`~grasp_env.core.state.State`, :class:`~grasp_env.core.state.Contact`
and :class:`~grasp_env.core.state.Event` (:mod:`~grasp_env.core.state`)."""
