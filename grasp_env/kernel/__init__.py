"""An env step's arithmetic, compiled: the move an action asks for, the analysis, reward and
observation of the state it reaches, for one env or for many at once. The single env
(:mod:`grasp_env.envs.frictionless_grasp`) and the batched one
(:mod:`grasp_env.envs.vector`) run the same functions, so that they agree bit for bit."""
