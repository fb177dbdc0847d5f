"""Batched env throughput: env steps/s of ``gymnasium.make_vec(env_id, num_envs=N)`` (the
batched env, one compiled call per step) against CartPole-v1's ``SyncVectorEnv`` and its own
numpy-batched vector env, measured in the same run; against N (1 to 256) and threads (1, 2);
the cost of a reset; where the time of a batched step goes; how the threads share a step
(the episodes' work on one thread and on all, and the share of the threads' time it fills,
taken costliest first or in index order); what its moves cost, by kind; and what the parts
of a move that touches the object cost.

Random actions (uniform, drawn in bulk from a seeded generator), resets included. Random
shapes are drawn from a shape pool (``shape_pool``, prepared before timing: its entries are
made once and reused, as in training). Each configuration is stepped for ``budget`` seconds
in each of ``rounds`` rounds, in a rotated order; reported are medians over rounds.

Usage: ``python -m benchmarks.batched [--quick]``
"""

from __future__ import annotations

import contextlib
import statistics
import time
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np
from numba import njit

import grasp_env
from benchmarks.common import headless, page_main, table, write
from grasp_env.kernel import step as kernel
from grasp_env.kernel.batch import cycles
from grasp_env.sim import contact_sets, motion, move
from grasp_env.sim.fall import touching
from grasp_env.sim.increment import newton
from grasp_env.sim.placement import place

IDS = ("FrictionlessGrasp-v0", "FrictionlessGraspRandomShapes-v0", "FrictionlessGraspLift-v0")
#: Pool of random shapes for the ids that draw them, prepared before timing.
POOL = 1024
#: Targets at 64 envs and the machine's threads: (id, baseline, least ratio).
TARGETS = (
    ("FrictionlessGrasp-v0", "CartPole-v1 SyncVectorEnv", 2.0),
    ("FrictionlessGraspLift-v0", "CartPole-v1 SyncVectorEnv", 0.5),
)
#: Untimed steps before a timed run of steps.
WARM_UP = 10
#: Back-to-back pairs of timed runs behind each target's ratio (:func:`paired_ratios`).
PAIRS = 9
#: Ratios reported without a verdict: (id, baseline).
RATIOS = (("FrictionlessGrasp-v0", "CartPole-v1 vector env"),)


def make(env_id: str, n: int, threads: int | None = None, pool: int = POOL):
    """The batched env of ``env_id`` with ``n`` sub-envs, its shape pool prepared."""
    kwargs = {"shape_pool": pool} if "shape_randomizer" in gym.spec(env_id).kwargs else {}
    venv = gym.make_vec(env_id, num_envs=n, threads=threads, **kwargs)
    prepare_pool(venv)
    return venv


def prepare_pool(venv) -> None:
    """Make every entry of the batched env's shape pool (if it has one) and its first episode
    before timing: in training, they are made as resets first draw them, then reused (a pool
    of 1024 is drawn through in the first few thousand resets of a run)."""
    first = venv.envs[0]
    for entry in range(first.shape_pool or 0):
        key = (0, entry)
        if key not in first._sims:
            first._sims[key] = grasp_env.Simulator(first._scene_of(key), first.contact_tol)
        sim = first._sims[key]
        state, error = first._first_state(sim, key)
        if error is None:
            first._new_episode(sim, state, None, key)


def rate(venv: gym.vector.VectorEnv, budget: float, seed: int) -> float:
    """Env steps/s of random actions for ``budget`` seconds (after ``WARM_UP`` untimed
    steps)."""
    draws = random_actions(venv, 4096, seed)
    venv.reset(seed=seed)
    for t in range(WARM_UP):
        venv.step(draws[t])
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < budget:
        for _ in range(16):
            venv.step(draws[steps % len(draws)])
            steps += 1
    return venv.num_envs * steps / (time.perf_counter() - start)


def paired_ratios(ours, baseline, pairs: int, budget: float) -> list[float]:
    """Ratios of ``ours``'s rate (:func:`rate`) to ``baseline``'s over ``pairs`` pairs of
    runs of ``budget`` seconds, each pair back to back in alternating order. A shared
    machine's speed drifts over minutes, and a Python baseline and a compiled batch slow
    down by different factors when its neighbours load it: the two runs of a pair see about
    the same state, the runs of the table above are minutes apart."""
    ratios = []
    for p in range(pairs):
        order = (ours, baseline) if p % 2 == 0 else (baseline, ours)
        first, second = (rate(venv, budget, seed=p) for venv in order)
        ratios.append(first / second if p % 2 == 0 else second / first)
    return ratios


def random_actions(venv: gym.vector.VectorEnv, steps: int, seed: int = 0) -> np.ndarray:
    """``steps`` batches of uniform random actions for ``venv``, drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    space, n = venv.single_action_space, venv.num_envs
    if isinstance(space, gym.spaces.Discrete):
        return rng.integers(space.n, size=(steps, n))
    return rng.uniform(space.low, space.high, (steps, n, *space.shape)).astype(np.float32)


@contextlib.contextmanager
def timing(owner, name: str, seconds: dict, key: str):
    """Within the block, add the wall time of every call of ``owner.name`` (a module's
    function or a class's method) to ``seconds[key]``; ``owner`` is restored after."""
    real, own = getattr(owner, name), vars(owner).get(name)

    def timed(*args, **kwargs):
        start = time.perf_counter()
        try:
            return real(*args, **kwargs)
        finally:
            seconds[key] += time.perf_counter() - start

    setattr(owner, name, timed)
    try:
        yield
    finally:
        if own is not None:
            setattr(owner, name, own)
        else:
            delattr(owner, name)


def reset_times(env_id: str, resets: int, pool: int = POOL) -> list[float]:
    """Seconds per ``reset()`` of a single env with a prepared shape pool."""
    venv = make(env_id, 1, pool=pool)
    env = venv.envs[0]
    env.reset(seed=0)
    out = []
    for _ in range(resets):
        start = time.perf_counter()
        env.reset()
        out.append(time.perf_counter() - start)
    return out


def step_parts(env_id: str, n: int, steps: int, pool: int = POOL) -> dict[str, float]:
    """Where a batched step's time goes: the compiled call, Python taking steps over, resets
    and the rest (gymnasium's API: actions checked, infos built), in seconds per step."""
    import grasp_env.envs.vector as vector

    venv = make(env_id, n, threads=1, pool=pool)
    draws = random_actions(venv, steps)
    venv.reset(seed=0)
    parts = {"compiled step": 0.0, "resets": 0.0, "Python's steps": 0.0}
    fallbacks = 0
    with (
        timing(vector, "step_batch", parts, "compiled step"),
        timing(type(venv.envs[0]), "_begin_episode", parts, "resets"),
        timing(vector.Episode, "advance", parts, "Python's steps"),
    ):
        start = time.perf_counter()
        for a in draws:
            venv.step(a)
            fallbacks += int((venv._status != kernel.OK).sum())
        total = time.perf_counter() - start
    parts["rest"] = total - sum(parts.values())
    return {k: v / steps for k, v in parts.items()} | {"steps Python took over": fallbacks}


@njit
def _cycle_counter() -> int:
    return cycles()


def cycles_per_second(seconds: float = 0.2) -> float:
    """The rate of the processor's cycle counter (the batch's measure of a step's cost)."""
    first, start = _cycle_counter(), time.perf_counter()
    time.sleep(seconds)
    return (_cycle_counter() - first) / (time.perf_counter() - start)


def thread_use(env_id: str, n: int, steps: int, pool: int = POOL) -> list[list]:
    """The same ``steps`` random-action steps of ``n`` envs (the same states: no result
    depends on the threads or the order) on one thread and on all, episodes taken
    costliest first or in index order (``cost`` zeroed before each step): the compiled
    call's time per step, the episodes' own work (the sum of their step costs), and the
    share of the threads' time it fills."""
    import grasp_env.envs.vector as vector

    rate_ = cycles_per_second()
    threads_max = numba.config.NUMBA_NUM_THREADS
    rows = []
    for threads, order in ((1, "costliest first"), (threads_max, "index order"),
                           (threads_max, "costliest first")):  # fmt: skip
        venv = make(env_id, n, threads, pool)
        draws = random_actions(venv, steps)
        venv.reset(seed=0)
        for a in draws[:WARM_UP]:
            venv.step(a)
        calls, work = {"compiled call": 0.0}, 0
        with timing(vector, "step_batch", calls, "compiled call"):
            for a in draws[WARM_UP:]:
                if order == "index order":
                    venv._cost[:] = 0
                venv.step(a)
                work += int(venv._cost.sum())
        wall = calls["compiled call"]
        seconds = work / rate_
        timed = steps - WARM_UP
        per_step, busy = 1e3 * seconds / timed, seconds / (threads * wall)
        rows.append([env_id, threads, order, f"{1e3 * wall / timed:.3f}", f"{per_step:.3f}",
                     f"{busy:.0%}"])  # fmt: skip
    return rows


@njit
def _timed_moves(model, q, h, target, keys, reps):
    """The last of ``reps`` runs of the compiled move (:func:`grasp_env.sim.move.run`, as a
    batched step calls it): ``(out, pose solves)``; a move that raises counts as touched."""
    out, solves = np.zeros(move.OUT_SIZE), np.zeros(1, dtype=np.int64)
    for _ in range(reps):
        solves[0] = 0
        try:
            out = move.run(model, q, h, target, keys, True, solves)[0]
        except Exception:  # timed as far as it got (Python would take the step over)
            out = np.zeros(move.OUT_SIZE)
    return out, solves[0]


#: Replays of each move :func:`move_costs` times.
REPLAYS = 5
#: Bands of pose solves a move needs, for :func:`move_costs`.
SOLVE_BANDS = ((0, 0), (1, 3), (4, 10), (11, 50), (51, None))


def _record_moves(env_id: str, steps: int, pool: int) -> tuple[list[tuple], object]:
    """The moves of ``steps`` random-action steps of a single env, each as ``(model, q, h,
    target, keys, consts)`` from the state it started in, and the env's settings."""
    venv = make(env_id, 1, threads=1, pool=pool)
    env = venv.envs[0]
    rng = np.random.default_rng(0)
    space = env.action_space
    env.reset(seed=0)
    moves = []
    for _ in range(steps):
        ep = env._episode
        action = rng.uniform(space.low, space.high)
        target = kernel.target_of(ep.consts, env._settings, ep.h, action)[0]
        moves.append(
            (ep.sim.compiled_model, ep.q.copy(), ep.h.copy(), target, ep.keys.copy(), ep.consts)
        )
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return moves, env._settings


def move_costs(env_id: str, steps: int, reps: int = REPLAYS, pool: int = POOL) -> list[tuple]:
    """What the moves of ``steps`` random-action steps of a single env cost in compiled code,
    by kind: the moves that touch nothing (the hand clear of an object resting on the
    support) and the others by the pose solves they need. Each move is replayed ``reps``
    times from the state it started in; a replay's time includes one call from Python (about
    a microsecond over ``reps``). Rows ``(kind, moves, share of moves, share of
    time, mean seconds)`` for the kinds that occurred."""
    moves, _ = _record_moves(env_id, steps, pool)
    kinds, times = [], []
    for args in moves:
        _timed_moves(*args[:5], 1)
        start = time.perf_counter()
        out, solves = _timed_moves(*args[:5], reps)
        times.append((time.perf_counter() - start) / reps)
        kinds.append(-1 if out[move.OUT_UNTOUCHED] else solves)
    kinds, times = np.array(kinds), np.array(times)
    groups = [("touch nothing", kinds == -1)]
    for lo, hi in SOLVE_BANDS:
        label = f"{lo}+" if hi is None else (f"{lo}" if lo == hi else f"{lo}-{hi}")
        upper = np.inf if hi is None else hi
        groups.append((f"touch, {label} pose solves", (kinds >= lo) & (kinds <= upper)))
    return [
        (label, int(mask.sum()), mask.mean(), times[mask].sum() / times.sum(), times[mask].mean())
        for label, mask in groups
        if mask.any()
    ]


@njit
def _move_end(model, q, h, target, keys):
    """The ``OUT_*`` array of the compiled move (:func:`grasp_env.sim.move.run`), raising
    where it raises."""
    return move.run(model, q, h, target, keys, True, np.zeros(1, dtype=np.int64))[0]


#: The parts of a move that touches the object :func:`touched_parts` times.
PART_NAMES = (
    "the whole move",
    "its first plan (contacts and motion LPs)",
    "contact detection alone",
    "a pose solve (Newton)",
    "the end's contacts and forces",
    "the analysis of the end state (form closure, y*)",
)


@njit
def _prepare(model, q, h, target, q1, h1):
    """What :func:`_part` needs made before it is timed: the first plan's outcome, active set
    and twist, and the contacts and rows of the move's end."""
    world = place(model, q, h)
    found = touching(model, world, contact_sets.empty())
    outcome, E, v = motion.plan(model, world, q, h, target - h, found, True)
    end_keys, rows = move.at_rest(model, q1, h1)
    return outcome, E, v, end_keys, rows


@njit
def _part(which, model, q, h, target, keys, consts, settings, q1, h1, prepared, reps):
    """Runs part ``which`` of :data:`PART_NAMES` ``reps`` times, each on its own: what it
    needs (the first plan of a pose solve, the end's contacts of its analysis) is
    ``prepared`` (:func:`_prepare`). Returns a number from its results, so that nothing is
    skipped; NaN for a pose solve where the first plan does not move the object."""
    outcome, E, v, end_keys, rows = prepared
    dh = target - h
    solves = np.zeros(1, dtype=np.int64)
    an = np.zeros(kernel.ANALYSIS)
    total = 0.0
    for _ in range(reps):
        if which == 0:
            total += move.run(model, q, h, target, keys, True, solves)[0][0]
        elif which == 1 or which == 2:
            world = place(model, q, h)
            found = touching(model, world, contact_sets.empty())
            total += found.shape[0]
            if which == 1:
                total += motion.plan(model, world, q, h, dh, found, True)[2][0]
        elif which == 3:
            if outcome != motion.MOVE or E.shape[0] == 0:
                return np.nan  # no pose to solve
            total += newton(model, q + 0.1 * v, h + 0.1 * dh, E, solves)[0][0]
        elif which == 4:
            total += move.at_rest(model, q1, h1)[0].shape[0]
        else:
            kernel.analyse(consts, settings, q1, h1, end_keys, rows, an)
            total += an[0]
    return total


def touched_parts(env_id: str, steps: int, reps: int = REPLAYS, pool: int = POOL) -> list[float]:
    """Mean seconds, over the moves of ``steps`` random-action steps of a single env that
    touch the object, of each part of :data:`PART_NAMES`, each replayed ``reps`` times from
    the state its move started in (a pose solve: one on the first plan's active set, where
    that plan moves the object, the others left out of its mean). Moves the compiled core
    hands to Python are left out."""
    moves, settings = _record_moves(env_id, steps, pool)
    sums, counts = np.zeros(len(PART_NAMES)), np.zeros(len(PART_NAMES))
    for model, q, h, target, keys, consts in moves:
        try:
            out = _move_end(model, q, h, target, keys)
            if out[move.OUT_UNTOUCHED]:
                continue
            q1, h1 = out[move.OUT_Q].copy(), out[move.OUT_H].copy()
            prepared = _prepare(model, q, h, target, q1, h1)
        except Exception:  # a move (or its first plan) the compiled core hands to Python
            continue
        for which in range(len(PART_NAMES)):
            args = (which, model, q, h, target, keys, consts, settings, q1, h1, prepared)
            if np.isnan(_part(*args, 1)):
                continue
            start = time.perf_counter()
            _part(*args, reps)
            sums[which] += (time.perf_counter() - start) / reps
            counts[which] += 1
    return list(sums / np.maximum(counts, 1))


def run(
    quick: bool,
    out: Path,
    *,
    pool: int = POOL,
    ids: tuple = IDS,
    budget: float | None = None,
    moves: int | None = None,
) -> Path:
    """Measure and write the page; ``pool``, ``ids``, ``budget`` (seconds per configuration
    and round) and ``moves`` (steps whose moves are replayed) make a smaller run."""
    headless()
    rounds = 1 if quick else 3
    pairs = 2 if quick else PAIRS
    budget = budget or (0.5 if quick else 3.0)
    sizes = (1, 64) if quick else (1, 4, 16, 64, 256)
    threads = sorted({1, numba.config.NUMBA_NUM_THREADS})
    configs = [("CartPole-v1 SyncVectorEnv", n, None) for n in sizes]
    configs += [("CartPole-v1 vector env", n, None) for n in sizes]
    configs += [(env_id, n, th) for env_id in ids for n in sizes for th in threads]
    envs = {}
    for name, n, th in configs:
        if name.startswith("CartPole"):
            mode = "sync" if "Sync" in name else "vector_entry_point"
            envs[name, n, th] = gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode=mode)
        else:
            envs[name, n, th] = make(name, n, th, pool)
    rates: dict[tuple, list[float]] = {key: [] for key in envs}
    for r in range(rounds):
        keys = list(envs)
        keys = keys[r % len(keys) :] + keys[: r % len(keys)]
        for key in keys:
            rates[key].append(rate(envs[key], budget, seed=r))
    med = {key: statistics.median(v) for key, v in rates.items()}
    threads_max = threads[-1]
    rows = []
    for name, n, th in envs:
        base = med["CartPole-v1 SyncVectorEnv", n, None]
        native = med["CartPole-v1 vector env", n, None]
        value = med[name, n, th]
        rows.append(
            [
                name,
                n,
                "-" if th is None else th,
                f"{value:,.0f}",
                f"{value / base:.2f}x",
                f"{value / native:.3f}x",
            ]
        )
    lines = [
        f"`python -m benchmarks.batched{' --quick' if quick else ''}`: env steps/s of random "
        f"actions, resets included, median of {rounds} round(s) of {budget:g} s; random shapes "
        f"from a prepared pool of {POOL}. Ratios are to CartPole-v1's `SyncVectorEnv` and to "
        "its numpy-batched vector env (`vector_entry_point`) with the same number of envs, "
        "measured in the same run.",
        "",
        *table(["env", "envs", "threads", "steps/s", "/ CartPole sync", "/ CartPole vector"], rows),
        "",
        "## Targets (64 envs, all threads)",
        "",
        f"Each ratio is the median over {pairs} pairs of runs of {budget:g} s, ours and the "
        "baseline back to back in alternating order (the range in brackets); the table's "
        "ratios above come from runs minutes apart.",
        "",
    ]
    for env_id, baseline, least in (*TARGETS, *((i, b, None) for i, b in RATIOS)):
        if env_id not in ids:
            continue
        ratios = paired_ratios(
            envs[env_id, 64, threads_max], envs[baseline, 64, None], pairs, budget
        )
        ratio, spread = statistics.median(ratios), f"{min(ratios):.2f}-{max(ratios):.2f}"
        if least is None:
            lines.append(f"- {env_id} / {baseline}: {ratio:.2f}x ({spread})")
        else:
            verdict = "met" if ratio >= least else "not met"
            lines.append(
                f"- target: {env_id} >= {least}x {baseline}: {ratio:.2f}x, {spread} ({verdict})"
            )
    resets = {env_id: reset_times(env_id, 20 if quick else 200, pool) for env_id in ids}
    lines += [
        "",
        "## Resets (a single env, shape pool prepared)",
        "",
        *table(
            ["env", "median ms", "p90 ms"],
            [
                [env_id, f"{1e3 * np.median(t):.3f}", f"{1e3 * np.percentile(t, 90):.3f}"]
                for env_id, t in resets.items()
            ],
        ),
        "",
        "## Where a batched step's time goes (64 envs, one thread, per step of all 64)",
        "",
    ]
    for env_id in ids:
        parts = step_parts(env_id, 64, 50 if quick else 400, pool)
        cells = ", ".join(
            f"{k} {v:,}" if isinstance(v, int) else f"{k} {1e3 * v:.3f} ms"
            for k, v in parts.items()
        )
        lines.append(f"- {env_id}: {cells}")
    thread_steps = 50 if quick else 400
    lines += [
        "",
        "## The threads (64 envs, per step of all 64)",
        "",
        f"The same {thread_steps} random-action steps on one thread and on "
        f"{threads_max}, the episodes taken costliest first (by their last step's cost, as "
        "the batch does) or in index order. `episodes' work` is the sum of the episodes' "
        "step costs (the processor's cycle counter, in ms): on more threads it grows where "
        "the threads slow each other down (shared caches and memory, the allocator); "
        "`threads busy` is the share of the call's time the threads spend on episodes, the "
        "rest waiting for the last episode of the step and starting the threads.",
        "",
        *table(
            ["env", "threads", "order", "compiled call ms", "episodes' work ms", "threads busy"],
            [row for env_id in ids for row in thread_use(env_id, 64, thread_steps, pool)],
        ),
    ]
    moves = moves or (500 if quick else 4000)
    lines += [
        "",
        f"## What the moves cost, by kind ({moves:,} random-action steps of a single env)",
        "",
        "Each move replayed in compiled code from the state it started in, "
        f"{REPLAYS} times (its time includes 1/{REPLAYS} of one call from Python). A move "
        "that touches the object costs in proportion to the pose solves it needs, each with "
        "its motion LP, contact detection and checks around it.",
        "",
        *table(
            ["env", "moves that", "moves", "share of moves", "share of time", "mean us"],
            [
                [env_id, kind, count, f"{share:.1%}", f"{time_share:.1%}", f"{1e6 * mean:.1f}"]
                for env_id in ids
                for kind, count, share, time_share, mean in move_costs(env_id, moves, pool=pool)
            ],
        ),
        "",
        f"## Inside a move that touches the object (the same {moves:,} steps)",
        "",
        "Mean us over the moves that touch the object, each part timed on its own, replayed "
        f"{REPLAYS} times from the state its move started in (the end's parts from the state "
        "it reached; the pose solve on the first plan's active set, a tenth of the way "
        "along). A move that touches the object plans its active set and twist again at most "
        "of its increments and solves the pose at each: the first plan and a pose solve show "
        "what an increment costs.",
        "",
        *table(
            ["env", *PART_NAMES],
            [
                [env_id, *(f"{1e6 * t:.1f}" for t in touched_parts(env_id, moves, pool=pool))]
                for env_id in ids
            ],
        ),
    ]
    return write(out, "Batched env throughput", lines)


def main(argv: list[str] | None = None) -> int:
    return page_main(argv, run, "batched.md", "short budgets, 1 and 64 envs")


if __name__ == "__main__":
    raise SystemExit(main())
