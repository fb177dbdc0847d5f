"""The paper's planner as a policy on FrictionlessGrasp-v0, saved as an animated GIF.

    python examples/scripted_policy.py [scene] [out.gif]

Runs headless. Needs imageio for the GIF (the ``viz`` extra); without it the frames are
rendered but not saved.
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym

import grasp_env  # noqa: F401  (registers FrictionlessGrasp-v0)
from agents.scripted import ScriptedPolicy


def main(scene: str = "fig13", path: str = "scripted_policy.gif", steps: int = 40) -> None:
    env = gym.make("FrictionlessGrasp-v0", scene=scene, render_mode="rgb_array")
    obs, info = env.reset(seed=0)
    policy = ScriptedPolicy(env)
    policy.reset(obs, info)
    frames = [env.render()]
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(policy.act(obs))
        frames.append(env.render())
        if terminated or truncated:
            break
    env.close()
    print(f"{scene}: success {info['is_success']}, y* = {info['grip_force']:.4f}")
    try:
        import imageio.v2 as imageio
    except ImportError:
        print("imageio is not installed (pip install 'grasp_env[viz]'): GIF not saved")
        return
    imageio.mimsave(path, frames, duration=100, loop=0)
    print(f"saved {len(frames)} frames to {path}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
