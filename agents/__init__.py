"""Policies for ``FrictionlessGrasp-v0``: the paper's scripted planner and PPO agents."""
