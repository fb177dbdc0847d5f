"""Shared test settings: headless pygame, derandomised hypothesis on CI, and the default run
in two processes (pytest-xdist, ``-n 2`` in pyproject's ``addopts``).

In parallel runs the tests of a module that share a module-scoped fixture (a planned grasp, a
trained model, a Ray run) go to one worker, so that the fixture is built once; and the
controller imports ``grasp_env`` and steps each env once before the workers start, so that
numba's on-disk cache is checked (and, after an edit of the compiled sources, cleared and
refilled) by one process rather than by both workers at once.
"""

import os

import pytest
from hypothesis import settings

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

# CI runs the same examples every time (a failure found locally becomes a regression test);
# locally hypothesis explores new examples on each run.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


def _parallel_controller(config: pytest.Config) -> bool:
    """This process hands tests to xdist workers (and runs none itself)."""
    workers = getattr(config.option, "numprocesses", None)
    return bool(workers) and not hasattr(config, "workerinput")


def pytest_configure(config: pytest.Config) -> None:
    if not _parallel_controller(config) or config.option.collectonly:
        return
    try:
        import gymnasium as gym

        import grasp_env  # noqa: F401  (registers the env ids)

        for env_id in ("FrictionlessGrasp-v0", "FrictionlessGraspLift-v0"):
            env = gym.make(env_id, palm_control=True)
            env.reset(seed=0)
            env.step(env.action_space.high)
            env.close()
    except Exception:  # the tests report what is broken
        pass


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests that use a module-scoped fixture of their module run on one worker
    (``--dist loadgroup``)."""
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        shared = any(
            d.scope == "module" and d.baseid
            for defs in info.name2fixturedefs.values()
            for d in defs
        )
        if shared:
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))
