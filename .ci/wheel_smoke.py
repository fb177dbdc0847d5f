"""Smoke test of an installed grasp_env wheel: the package data and the env work outside the
repository.

Build the wheel, install it into a fresh venv, then run this script with that venv's Python::

    .venv/bin/pip wheel . -w /tmp/whl --no-deps
    python -m venv /tmp/wv && /tmp/wv/bin/pip install /tmp/whl/grasp_env-*.whl
    /tmp/wv/bin/python .ci/wheel_smoke.py

It works in a new empty temporary folder (which holds a folder named ``fig13``, as a second
``python -m agents.scripted --scene fig13 --out fig13`` would leave) and checks that
``grasp_env`` is imported from the install, not from a source checkout; that the bundled
scenes are there and load by name; that ``gymnasium.make("FrictionlessGrasp-v0")`` resets and
steps; and that ``render_mode="rgb_array"`` gives a frame. It prints one line starting with
``wheel smoke test OK`` and exits 0, or exits 1 with the failure.
"""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import sys
import tempfile
import traceback
from pathlib import Path

#: Scenes every install must ship (the default scene first).
REQUIRED_SCENES = ("fig13", "square", "tall_rectangle", "triangle", "pentagon", "hexagon")
STEPS = 5


def smoke() -> str:
    """Run the checks; return the success line (AssertionError on a failure)."""
    import gymnasium as gym
    import numpy as np

    import grasp_env

    package = Path(grasp_env.__file__).resolve().parent
    assert not (package.parent / "pyproject.toml").exists(), (
        f"grasp_env is imported from a source checkout ({package}), not from an install"
    )
    scenes = grasp_env.bundled_scenes()
    missing = sorted(set(REQUIRED_SCENES) - set(scenes))
    assert not missing, f"bundled scenes missing from the install: {missing} (have {scenes})"
    Path("fig13").mkdir()  # a bundled name must not read the working directory
    scene = grasp_env.load_scene("fig13")
    assert scene.name == "fig13", scene.name

    env = gym.make("FrictionlessGrasp-v0", render_mode="rgb_array")
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs), "reset observation outside the space"
    env.action_space.seed(0)
    for _ in range(STEPS):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs), "step observation outside the space"
        assert np.isfinite(reward), reward
        assert "sim_error" not in info, info.get("sim_error")
        if terminated or truncated:
            obs, info = env.reset()
    frame = env.render()
    env.close()
    assert isinstance(frame, np.ndarray) and frame.dtype == np.uint8, type(frame)
    assert frame.ndim == 3 and frame.shape[2] == 3, frame.shape
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3, "the frame is blank"
    return (
        f"wheel smoke test OK: grasp_env {grasp_env.__version__} from {package}; "
        f"{len(scenes)} bundled scenes; FrictionlessGrasp-v0 reset + {STEPS} steps; "
        f"rgb_array frame {frame.shape}"
    )


def main() -> int:
    old = Path.cwd()
    with tempfile.TemporaryDirectory(prefix="grasp_env_wheel_smoke_") as tmp:
        os.chdir(tmp)
        try:
            line = smoke()
        except Exception as exc:  # the traceback, then one line naming the failure
            traceback.print_exc()
            print(f"wheel smoke test FAILED: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 1
        finally:
            os.chdir(old)
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
