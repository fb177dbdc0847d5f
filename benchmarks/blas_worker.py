"""One worker of the BLAS-variation benchmark (:mod:`benchmarks.blas_variation`): the seeded
episodes of one suite played in this process, under the OpenBLAS core type it was started
with, and recorded at reset and after every step (a bit-exact digest of the state, the
object pose and the discrete outcome), with the OpenBLAS libraries ``threadpoolctl`` reports."""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from benchmarks.common import headless

#: The variables that switch OpenBLAS to other kernels.
BLAS_VARS = ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE")


def blas_libraries() -> list[dict[str, Any]]:
    """The loaded OpenBLAS libraries: file, version, architecture (``threadpoolctl``)."""
    from threadpoolctl import threadpool_info

    return [
        {
            "library": "/".join(Path(i["filepath"]).parts[-2:]),
            "version": i.get("version"),
            "architecture": i.get("architecture"),
        }
        for i in threadpool_info()
        if i.get("internal_api") == "openblas"
    ]


def step_record(env: Any, info: dict, terminated: bool, truncated: bool) -> list[Any]:
    """``[digest, object pose, discrete outcome]`` of the env's current state."""
    import numpy as np

    from benchmarks.episodes import contact_keys

    state = env.unwrapped.state
    parts = [state.object_pose, state.hand]
    for c in state.contacts:
        parts += [c.point, c.normal, [c.force]]
    raw = np.concatenate([np.asarray(p, dtype=np.float64).ravel() for p in parts]).tobytes()
    error = info.get("sim_error")
    discrete = [
        contact_keys(env),
        list(info["events"]) if error is None else [],  # a failed step keeps the old ones
        bool(info["jammed"]),
        bool(info["hand_blocked"]),
        bool(info["form_closure"]),
        bool(terminated),
        bool(truncated),
        bool(info["is_success"]),
        None if error is None else str(error).split(":", 1)[0],
    ]
    digest = hashlib.blake2b(raw, digest_size=12).hexdigest()
    return [digest, [float(x) for x in state.object_pose], discrete]


def play(suite: str, seed: int, steps: int) -> dict[str, Any]:
    """Play episode ``(suite, seed)`` for up to ``steps`` steps; its per-step records."""
    from benchmarks.episodes import action_rng, make_env, random_action, start_of

    env, kind = make_env(suite, seed)
    rng = action_rng(seed)
    records: list[list[Any]] = []
    try:
        _, info = env.reset(seed=seed)
        records.append(step_record(env, info, False, False))
        for _ in range(steps):
            _, _, terminated, truncated, info = env.step(random_action(rng))
            records.append(step_record(env, info, terminated, truncated))
            if terminated or truncated:
                break
    except Exception as exc:  # an outcome too: it ends the episode, recorded as its last step
        records.append([f"raised {type(exc).__name__}", [], ["raised", type(exc).__name__]])
    env.close()
    return {"seed": seed, "start": start_of(seed), "kind": kind, "steps": records}


def worker(suite: str, seeds: Sequence[int], steps: int) -> dict[str, Any]:
    """The record of one worker process: its BLAS environment, libraries and episodes."""
    headless()
    t0 = time.process_time()
    episodes = [play(suite, s, steps) for s in seeds]
    return {
        "suite": suite,
        "environ": {k: os.environ.get(k) for k in BLAS_VARS},
        "blas": blas_libraries(),  # after the episodes: scipy's OpenBLAS is loaded by then
        "cpu": time.process_time() - t0,
        "episodes": episodes,
    }
