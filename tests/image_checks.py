"""Checks on rendered images shared by the rendering and figure tests."""

from __future__ import annotations

import numpy as np


def ink_runs(image: np.ndarray, limit: int = 100) -> list[int]:
    """Heights of the runs of pixel rows holding dark (text) pixels."""
    dark = (image[..., :3].max(axis=-1) < limit).any(axis=1)
    runs, n = [], 0
    for d in dark:
        if d:
            n += 1
        elif n:
            runs.append(n)
            n = 0
    return runs + ([n] if n else [])
