"""Many episodes advanced by one call: :func:`grasp_env.kernel.step.step_env` for each, spread
over the machine's cores (numba's ``prange``). Each episode's arithmetic is the single env's,
and no episode reads another's arrays, so the results do not depend on the number of
threads, nor on which thread steps which episode.

The threads share the episodes dynamically: each takes the next episode not yet taken
(an atomic counter) until none is left. A step's cost is heavy-tailed (most moves touch
nothing, a fall takes a hundred times longer), so a static split leaves one thread waiting
on the other.

The episodes' arrays are stacked: row ``i`` of each is episode ``i``'s, its contacts padded
to the buffers' length with their count beside them, its model the ``i``-th of a typed list.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from grasp_env.compiled import CACHE
from grasp_env.kernel import step


@intrinsic
def take_next(typingctx, counter):
    """``counter[0]`` before adding 1 to it, atomically: the next episode for the calling
    thread (``counter`` a 1-d int64 array)."""
    sig = types.int64(counter)

    def codegen(context, builder, signature, args):
        array_type = signature.args[0]
        array = context.make_array(array_type)(context, builder, args[0])
        first = context.get_constant(types.intp, 0)
        pointer = cgutils.get_item_pointer(context, builder, array_type, array, [first])
        one = context.get_constant(types.int64, 1)
        return builder.atomic_rmw("add", pointer, one, "monotonic")

    return sig, codegen


@njit(cache=CACHE)
def step_one(
    i, models, consts, settings, q, h, keys, rows, counts, an, ep, obs, low, high, actions,
    seen, info, status,
) -> None:  # fmt: skip
    """One step of episode ``i`` (see :func:`step_batch`)."""
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
    if code == step.OK and n > keys.shape[1]:
        code = step.TOO_MANY_CONTACTS
    status[i] = code
    if code != step.OK:
        return
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


@njit(cache=CACHE, parallel=True)
def step_batch(
    models, consts, settings, q, h, keys, rows, counts, an, ep, obs, low, high, actions,
    seen, info, status, threads,
) -> None:  # fmt: skip
    """One step of every episode: row ``i`` of ``q``, ``h``, ``keys``/``rows`` (the first
    ``counts[i]``), ``an``, ``ep`` and ``obs`` moves on by ``actions[i]``, its observation
    into ``seen[i]`` and its info into ``info[i]`` (:data:`grasp_env.kernel.step.INFO`).
    ``status[i]`` is :func:`grasp_env.kernel.step.step_env`'s, or ``TOO_MANY_CONTACTS``
    where the state reached has more contacts than the buffers hold; where it is not ``OK``
    the episode's rows are left as they were, for Python to take the step over. ``threads``:
    the threads numba runs the call on (``numba.get_num_threads()``, which compiled code
    could read only at the cost of numba's on-disk cache)."""
    n = q.shape[0]
    counter = np.zeros(1, dtype=np.int64)
    for _ in prange(min(threads, n)):
        while True:
            i = take_next(counter)
            if i >= n:
                break
            step_one(
                np.int64(i), models, consts, settings, q, h, keys, rows, counts, an, ep, obs,
                low, high, actions, seen, info, status,
            )  # fmt: skip
