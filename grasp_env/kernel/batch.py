"""Many episodes advanced by one call: :func:`grasp_env.kernel.step.step_env` for each, spread
over the machine's cores (numba's ``prange``). Each episode's arithmetic is the single env's,
and no episode reads another's arrays, so the results do not depend on the number of
threads, nor on which thread steps which episode.

The threads share the episodes dynamically: each takes the next episode not yet taken
(an atomic counter) until none is left. A step's cost is heavy-tailed (most moves touch
nothing, a fall takes a hundred times longer), so a static split leaves one thread waiting
on the other. The episodes are taken costliest first, by what their last step cost (the
processor's cycle counter, where it has one): a costly step is most often followed by
another (a hand pressing on the object goes on pressing), and taken last it would leave the
other threads idle. That order is a schedule only; no result depends on it.

The episodes' arrays are stacked: row ``i`` of each is episode ``i``'s, its contacts padded
to the buffers' length with their count beside them, its model the ``i``-th of a typed list.
"""

from __future__ import annotations

import platform

import llvmlite.ir as llvmir
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


#: Whether the processor has a cycle counter user code may read (x86's time-stamp counter;
#: elsewhere LLVM's ``readcyclecounter`` may read a register that traps or reads 0).
HAS_CYCLE_COUNTER = platform.machine().lower() in ("x86_64", "amd64", "i386", "i686")


@intrinsic
def cycles(typingctx):
    """The processor's cycle counter (LLVM's ``readcyclecounter``; 0 without
    :data:`HAS_CYCLE_COUNTER`, and the episodes go in index order): what a step cost, for the
    order of the next."""
    sig = types.int64()

    def codegen(context, builder, signature, args):
        if not HAS_CYCLE_COUNTER:
            return context.get_constant(types.int64, 0)
        fnty = llvmir.FunctionType(llvmir.IntType(64), [])
        counter = cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(counter, [])

    return sig, codegen


@njit(cache=CACHE)
def step_one(
    i, models, consts, q, h, keys, rows, counts, an, ep, obs, actions, seen, info, status, mine,
) -> None:  # fmt: skip
    """One step of episode ``i`` (see :func:`step_batch`) in the calling thread's buffers
    ``mine`` (:func:`thread_buffers`): rows of the stacked arrays are views sharing one
    reference count, which every call would change from every thread at once, and fresh
    copies would cost an allocation each."""
    settings, low, high, my_consts, my_q, my_h, my_keys, my_rows, my_an, my_ep, my_obs = mine[:11]
    my_action, my_info = mine[11:]
    m = counts[i]
    my_consts[:] = consts[i]
    my_q[:] = q[i]
    my_h[:] = h[i]
    my_keys[:m] = keys[i, :m]
    my_rows[:m] = rows[i, :m]
    my_an[:] = an[i]
    my_ep[:] = ep[i]
    my_obs[:] = obs[i]
    my_action[:] = actions[i]
    my_info[:] = 0.0
    state = (my_q, my_h, my_keys[:m], my_rows[:m])
    result = step.step_env(
        models[i], my_consts, settings, state, my_an, my_ep, my_obs, low, high, my_action,
        my_info,
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
    an[i] = my_an
    ep[i] = my_ep
    obs[i] = my_obs
    info[i] = my_info
    seen[i] = observed


@njit(cache=CACHE)
def thread_buffers(settings, low, high, consts, q, h, keys, rows, an, ep, obs, actions, info):
    """One thread's copies of the arrays every episode reads (``settings``, ``low``,
    ``high``) and its buffers for one episode's rows of the others, in
    :func:`step_one`'s order."""
    return (
        settings.copy(), low.copy(), high.copy(), np.empty(consts.shape[1]),
        np.empty(q.shape[1]), np.empty(h.shape[1]), np.empty(keys.shape[1:], keys.dtype),
        np.empty(rows.shape[1:]), np.empty(an.shape[1]), np.empty(ep.shape[1]),
        np.empty(obs.shape[1], obs.dtype), np.empty(actions.shape[1]), np.empty(info.shape[1]),
    )  # fmt: skip


@njit(cache=CACHE, parallel=True)
def step_batch(
    models, consts, settings, q, h, keys, rows, counts, an, ep, obs, low, high, actions,
    seen, info, status, threads, cost,
) -> None:  # fmt: skip
    """One step of every episode: row ``i`` of ``q``, ``h``, ``keys``/``rows`` (the first
    ``counts[i]``), ``an``, ``ep`` and ``obs`` moves on by ``actions[i]``, its observation
    into ``seen[i]`` and its info into ``info[i]`` (:data:`grasp_env.kernel.step.INFO`).
    ``status[i]`` is :func:`grasp_env.kernel.step.step_env`'s, or ``TOO_MANY_CONTACTS``
    where the state reached has more contacts than the buffers hold; where it is not ``OK``
    the episode's rows are left as they were, for Python to take the step over. ``threads``:
    the threads numba runs the call on (``numba.get_num_threads()``, which compiled code
    could read only at the cost of numba's on-disk cache). ``cost[i]``: the cycles episode
    ``i``'s last step took, the order of this one's (costliest first), updated."""
    n = q.shape[0]
    counter = np.zeros(1, dtype=np.int64)
    order = np.argsort(-cost, kind="mergesort")
    for _ in prange(min(threads, n)):
        mine = thread_buffers(settings, low, high, consts, q, h, keys, rows, an, ep, obs,
                              actions, info)  # fmt: skip
        while True:
            k = take_next(counter)
            if k >= n:
                break
            i = order[k]
            start = cycles()
            step_one(
                i, models, consts, q, h, keys, rows, counts, an, ep, obs, actions, seen, info,
                status, mine,
            )  # fmt: skip
            cost[i] = cycles() - start
