"""The grasp analysis of the paper's section 2: contact geometry
(:mod:`~grasp_env.mechanics.contacts`), form and force closure and the grip objective ``y*``
(:mod:`~grasp_env.mechanics.closure`), tippability (:mod:`~grasp_env.mechanics.tippability`,
its regions' records in :mod:`~grasp_env.mechanics.tip_regions`) and width
(:mod:`~grasp_env.mechanics.width`)."""
