"""FrictionlessGrasp-v0 quick start: 50 random steps, saved as an animated GIF.

    python examples/env_quickstart.py [out.gif]

Runs headless (SDL_VIDEODRIVER=dummy is set if no display is configured). Needs Pillow for the
GIF (it comes with matplotlib); without it the frames are rendered but not saved.
"""

from __future__ import annotations

import os
import sys

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import gymnasium as gym
import numpy as np

import grasp_env  # noqa: F401  (registers FrictionlessGrasp-v0)


def main(path: str = "env_quickstart.gif", steps: int = 50, seed: int = 0) -> None:
    env = gym.make(
        "FrictionlessGrasp-v0", scene="fig13", start="preliftoff", render_mode="rgb_array"
    )
    env.action_space.seed(seed)
    _, info = env.reset(seed=seed)
    frames = [env.render()]
    total = 0.0
    for _ in range(steps):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        total += reward
        frames.append(env.render())
        if terminated or truncated:
            _, info = env.reset()
    env.close()
    print(
        f"{steps} random steps: return {total:.3f}, last info: form closure "
        f"{info['form_closure']}, dropped {info['dropped']}"
    )
    try:
        from PIL import Image
    except ImportError:
        print("Pillow is not installed (pip install pillow): frames rendered, GIF not saved")
        return
    images = [Image.fromarray(np.asarray(f)) for f in frames]
    fps = env.metadata["render_fps"]
    images[0].save(path, save_all=True, append_images=images[1:], duration=1000 // fps, loop=0)
    print(f"saved {len(images)} frames to {path}")


if __name__ == "__main__":
    main(*sys.argv[1:2])
