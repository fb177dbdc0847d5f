"""Many episodes advanced by one call: :func:`grasp_env.kernel.step.step_env` for each, spread
over the machine's cores (numba's ``prange``). Each episode's arithmetic is the single env's,
and no episode reads another's arrays, so the results do not depend on the number of
threads.

The episodes' arrays are stacked: row ``i`` of each is episode ``i``'s, its contacts padded
to the buffers' length with their count beside them, its model the ``i``-th of a typed list.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from grasp_env.compiled import CACHE
from grasp_env.kernel import step


@njit(cache=CACHE, parallel=True)
def step_batch(
    models, consts, settings, q, h, keys, rows, counts, an, ep, obs, low, high, actions,
    seen, info, status,
) -> None:  # fmt: skip
    """One step of every episode: row ``i`` of ``q``, ``h``, ``keys``/``rows`` (the first
    ``counts[i]``), ``an``, ``ep`` and ``obs`` moves on by ``actions[i]``, its observation
    into ``seen[i]`` and its info into ``info[i]`` (:data:`grasp_env.kernel.step.INFO`).
    ``status[i]`` is :func:`grasp_env.kernel.step.step_env`'s, or ``TOO_MANY_CONTACTS``
    where the state reached has more contacts than the buffers hold; where it is not ``OK``
    the episode's rows are left as they were, for Python to take the step over."""
    capacity = keys.shape[1]
    for j in prange(q.shape[0]):
        i = np.int64(j)  # the list of models takes a signed index
        m = counts[i]
        # private copies: rows of the stacked arrays are views sharing one reference count,
        # which every call would change from every thread at once
        state = (q[i].copy(), h[i].copy(), keys[i, :m].copy(), rows[i, :m].copy())
        mine_an, mine_ep, mine_obs = an[i].copy(), ep[i].copy(), obs[i].copy()
        mine_info = np.zeros(info.shape[1])
        result = step.step_env(
            models[i], consts[i].copy(), settings.copy(), state, mine_an, mine_ep, mine_obs,
            low.copy(), high.copy(), actions[i].copy(), mine_info,
        )  # fmt: skip
        code, observed, _, _, q_new, h_new, new_keys, new_rows, _ = result
        n = new_keys.shape[0]
        if code == step.OK and n > capacity:
            code = step.TOO_MANY_CONTACTS
        status[i] = code
        if code != step.OK:
            continue
        q[i] = q_new
        h[i] = h_new
        counts[i] = n
        keys[i, :n] = new_keys
        rows[i, :n] = new_rows
        an[i] = mine_an
        ep[i] = mine_ep
        obs[i] = mine_obs
        info[i] = mine_info
        seen[i] = observed
