"""How often the scripted planner lifts random convex shapes, why it fails where it does, and
what a plan costs.

Three suites of random shapes on the fig13 hand. ``heldout`` (the env's default ranges) and
``wide`` (``WIDE_SHAPE_RANGES``: 3-12 vertices, aspect to 1:5): shape ``k`` is the env's
shape for ``reset(seed=HELDOUT_SEED + k)``, the held-out shapes of ``agents.evaluate``.
``small`` samples where the planner fails: polygons of 3-5 vertices, 0.15-0.6 palm widths
wide, low or high (:data:`SMALL_BANDS`), 0.08-0.55 high, drawn by the env's randomizer from
``SMALL_SEED + k``, seeds no test or training uses. For each shape: whether it is tippable
(the paper's criterion: a tippability region is non-empty; without one no frictionless grasp
can lift it), the whole plan (:func:`grasp_env.planning.plan_grasp`), its outcome re-checked
on the final state, and its CPU time. ``--env`` adds the scripted policy
(``agents.scripted.ScriptedPolicy``) through the env on the env's suites' shapes, as
``agents.evaluate`` runs it.

Usage: ``python -m benchmarks.planner_shapes [--shapes N] [--suites heldout wide small]
[--env] [--timeout T] [--workers W] [--out FILE]`` from the repository root.
"""

from __future__ import annotations

import statistics
from collections import Counter
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from benchmarks.common import BudgetExceeded, headless, parser, table, time_limit, write
from grasp_env.cli import positive_int, seconds, workers

SUITES = ("heldout", "wide", "small")
#: Targets of every suite: the share of tippable shapes lifted, and a plan's CPU seconds
#: (median and largest, over the tippable shapes).
LIFTED_TARGET, MEDIAN_CPU_TARGET, MAX_CPU_TARGET = 0.95, 0.5, 10.0
#: The suites whose shapes are the env's (``agents.episodes.SHAPE_SUITES``), which ``--env``
#: runs the scripted policy on.
ENV_SUITES = ("heldout", "wide")

#: First seed of the ``small`` suite, apart from the env's held-out seeds and from training's.
SMALL_SEED = 2_000_000
#: Width bands of the ``small`` suite (palm widths), crossed with its profiles.
SMALL_WIDTHS = ((0.15, 0.3), (0.3, 0.45), (0.45, 0.6))
#: Profiles of the ``small`` suite: height over width.
SMALL_PROFILES = {"low": (0.15, 0.6), "high": (0.6, 1.5)}
#: The ``small`` suite's bands in the order its shapes cycle through them: shape ``k`` is in
#: band ``k % len(SMALL_BANDS)``.
SMALL_BANDS = tuple((width, profile) for width in SMALL_WIDTHS for profile in SMALL_PROFILES)
#: Heights of the ``small`` suite's shapes (palm widths).
SMALL_HEIGHT = (0.08, 0.55)


def band_name(band: tuple[tuple[float, float], str]) -> str:
    (lo, hi), profile = band
    return f"{lo:g}-{hi:g} w, {profile}"


def small_scene(k: int):
    """Shape ``k`` of the ``small`` suite: the env's randomizer (3-5 vertices, fig13's hand
    set-up) seeded with ``SMALL_SEED + k``, its draws kept only in shape ``k``'s band."""
    import numpy as np

    import grasp_env
    from grasp_env.envs.shapes import random_shape_scene

    (w_lo, w_hi), profile = SMALL_BANDS[k % len(SMALL_BANDS)]
    r_lo, r_hi = SMALL_PROFILES[profile]

    def outside(scene) -> str | None:
        width, height = np.ptp(scene.object.vertices_W0, axis=0)
        if not (w_lo <= width < w_hi and r_lo <= height / width < r_hi):
            return "outside the band"
        if not SMALL_HEIGHT[0] <= height <= SMALL_HEIGHT[1]:
            return "outside the heights"
        return None

    # A polygon's diameter is at least its width and at most its width times sqrt(1 + r^2).
    ranges = {"vertices": (3, 5), "size": (w_lo, w_hi * float(np.hypot(1.0, r_hi)))}
    rng = np.random.default_rng(SMALL_SEED + k)
    return random_shape_scene(rng, grasp_env.load_scene("fig13"), ranges, outside)


def suite_scene(suite: str, k: int):
    """Shape ``k`` of ``suite``: for an env suite the scene of the env's
    ``reset(seed=HELDOUT_SEED + k)``, for ``small`` :func:`small_scene`."""
    if suite == "small":
        return small_scene(k)
    import gymnasium as gym

    from agents.episodes import HELDOUT_SEED, SHAPE_SUITES

    env = gym.make("FrictionlessGrasp-v0", **SHAPE_SUITES[suite])
    env.reset(seed=HELDOUT_SEED + k)
    scene = env.unwrapped.simulator.scene
    env.close()
    return scene


def plan_one(suite: str, k: int, timeout: float) -> dict:
    """Plan a grasp of shape ``k`` of ``suite``; the outcome as a dict."""
    import numpy as np

    from grasp_env import planning
    from grasp_env.mechanics import closure as mech
    from grasp_env.mechanics.tippability import tippability_regions
    from grasp_env.planning.grasp import has_face_turned_down

    scene = suite_scene(suite, k)
    left, right = tippability_regions(scene)
    row = {
        "suite": suite,
        "k": k,
        "vertices": len(scene.object.vertices_B),
        "band": band_name(SMALL_BANDS[k % len(SMALL_BANDS)]) if suite == "small" else "",
        "tippable": not (left.is_empty and right.is_empty),
        "face_down": has_face_turned_down(scene),
    }
    try:
        with time_limit(timeout):
            plan = planning.plan_grasp(scene)
    except BudgetExceeded:
        over = {"status": "timeout", "checked": False, "reason": f"over {timeout:g} s"}
        return {**row, **over, "cpu": timeout}
    final = plan.steps[-1].state if plan.steps else None
    checked = (
        final is not None
        and not final.on_support
        and mech.is_form_closure(final)
        and bool(np.all(np.isfinite(final.object_pose)))
    )
    return {
        **row,
        "status": plan.status,
        "checked": checked,
        "reason": "" if plan.success else plan.message,
        "placement": plan.placement,
        "explored": "exploratory" in plan.placement,
        "grip": plan.steps[-1].grip / scene.object_weight if plan.success else None,
        "cpu": plan.cpu_time,
    }


def env_one(suite: str, k: int, timeout: float) -> dict:
    """The scripted policy's episode on shape ``k`` of ``suite`` through the env."""
    from agents.episodes import HELDOUT_SEED, SCRIPTED_KWARGS, PolicySpec, run_episode

    spec = PolicySpec("scripted", "scripted", SCRIPTED_KWARGS)
    try:
        with time_limit(timeout):
            ep = run_episode(spec, suite, f"shape_{HELDOUT_SEED + k}", HELDOUT_SEED + k, None)
    except BudgetExceeded:
        return {"suite": suite, "k": k, "success": False, "error": f"over {timeout:g} s"}
    return {
        "suite": suite,
        "k": k,
        "success": ep.success,
        "steps": ep.steps,
        "error": ep.error,
    }


def _job(job: tuple) -> dict:
    kind, suite, k, timeout = job
    return (plan_one if kind == "plan" else env_one)(suite, k, timeout)


def _lifted(row: dict) -> bool:
    return row["status"] == "form_closure" and row["checked"]


def _reason(row: dict) -> str:
    """A failed plan's reason, shortened to its kind, and whether the object has no face
    turned down besides its supporting edge."""
    from grasp_env.planning.grasp import NO_FACE_DOWN

    if row["status"] in ("timeout", "error"):
        return row["status"]
    if row["status"] == "form_closure":
        return "lifted but the final state fails the re-check"
    kind = row["reason"].split(":")[0]
    return f"{kind}; {NO_FACE_DOWN}" if NO_FACE_DOWN in row["reason"] else kind


def _wilson(k: int, n: int) -> str:
    from agents.summary import wilson

    lo, hi = wilson(k, n)
    return f"{k}/{n} ({100 * k / n:.0f}%, 95% CI {100 * lo:.0f}-{100 * hi:.0f}%)" if n else "-"


def _by_suite(records: list[dict]) -> Iterator[tuple[str, list[dict]]]:
    """Each suite of ``SUITES`` that has records, in that order, with its records."""
    for suite in SUITES:
        mine = [r for r in records if r["suite"] == suite]
        if mine:
            yield suite, mine


def _groups(plans: list[dict]) -> Iterator[tuple[str, str, tuple[int, int]]]:
    """Per suite, each vertex count (and in ``small`` each band) with its tippable shapes
    lifted and tippable shapes."""
    for suite, mine in _by_suite(plans):
        tippable = [r for r in mine if r["tippable"]]
        keys = [(f"{n} vertices", "vertices", n) for n in sorted({r["vertices"] for r in mine})]
        if suite == "small":
            keys += [(band_name(b), "band", band_name(b)) for b in SMALL_BANDS]
        for name, field, value in keys:
            group = [r for r in tippable if r[field] == value]
            yield suite, name, (sum(_lifted(r) for r in group), len(group))


def _no_face_down(plans: list[dict]) -> Iterator[list[object]]:
    """Per suite: the tippable shapes with no face turned down (by vertex count), how many
    of them are lifted, and how many of the suite's failures they are."""
    for suite, mine in _by_suite(plans):
        tippable = [r for r in mine if r["tippable"]]
        flat = [r for r in tippable if not r["face_down"]]
        counts = Counter(r["vertices"] for r in flat)
        by_count = ", ".join(f"{n} with {v} vertices" for v, n in sorted(counts.items()))
        fails = [r for r in tippable if not _lifted(r)]
        yield [
            suite,
            f"{len(flat)} ({by_count})" if flat else "0",
            sum(_lifted(r) for r in flat),
            f"{sum(not r['face_down'] for r in fails)} of {len(fails)}",
        ]


def _targets(plans: list[dict]) -> list[str]:
    """A line per suite and target: the share of tippable shapes lifted, a plan's median
    and largest CPU time."""

    def verdict(ok: bool) -> str:
        return "met" if ok else "not met"

    lines = []
    for suite, mine in _by_suite(plans):
        tippable = [r for r in mine if r["tippable"]]
        if not tippable:
            continue
        lifted = sum(_lifted(r) for r in tippable)
        share = lifted / len(tippable)
        cpu = [r["cpu"] for r in tippable]
        median, most = statistics.median(cpu), max(cpu)
        lines += [
            f"* target: >= {LIFTED_TARGET:.0%} of tippable `{suite}` shapes lifted: "
            f"**{lifted}/{len(tippable)} = {share:.0%}** ({verdict(share >= LIFTED_TARGET)})",
            f"* target: median plan on `{suite}` <= {MEDIAN_CPU_TARGET:g} s of CPU: "
            f"**{median:.2f} s** ({verdict(median <= MEDIAN_CPU_TARGET)})",
            f"* target: largest plan on `{suite}` <= {MAX_CPU_TARGET:g} s of CPU: "
            f"**{most:.2f} s** ({verdict(most <= MAX_CPU_TARGET)})",
        ]
    return lines


def report(plans: list[dict], episodes: list[dict], timeout: float) -> list[str]:
    """The page's body: per suite, the outcome counts, failure reasons and CPU times, then the
    scripted policy through the env, then every failure."""
    body = [
        "Shapes: the env's held-out random shapes (`reset(seed=1_000_000 + k)`) on the fig13 "
        "hand; `heldout` in the default ranges, `wide` in `WIDE_SHAPE_RANGES`; `small`: 3-5 "
        "vertices, 0.15-0.6 palm widths w wide and 0.08-0.55 w high, low (height 0.15-0.6 "
        "of the width) or high (0.6-1.5), cycling through the bands (seeds 2_000_000 + k). "
        "Wall limit "
        f"{timeout:g} s a plan. `lifted`: the final state re-checked to be in form closure "
        "with the object off the support. Tippable: a non-empty tippability region (the "
        "paper's criterion; an object without one cannot be lifted without friction).",
        "",
    ]
    rows = []
    for suite, mine in _by_suite(plans):
        tippable = [r for r in mine if r["tippable"]]
        lifted = [r for r in tippable if _lifted(r)]
        cpu = [r["cpu"] for r in tippable]
        rows.append(
            [
                suite,
                len(mine),
                len(mine) - len(tippable),
                len(tippable),
                _wilson(len(lifted), len(tippable)),
                sum(r.get("explored", False) for r in lifted),
                f"{statistics.median(cpu):.2f}" if cpu else "-",
                f"{max(cpu):.2f}" if cpu else "-",
            ]
        )
    body += table(
        [
            "suite",
            "shapes",
            "not tippable",
            "tippable",
            "tippable lifted",
            "lifted by exploration",
            "CPU median (s)",
            "CPU max (s)",
        ],
        rows,
        align="lrrrrrrr",
    )
    body += ["", *_targets(plans)]
    body += ["", "Tippable shapes lifted by vertex count (and, in `small`, by band):", ""]
    body += table(
        ["suite", "group", "tippable lifted"],
        [[suite, group, _wilson(*counts)] for suite, group, counts in _groups(plans)],
        align="lll",
    )
    body += [
        "",
        "Tippable shapes with no face turned down besides their supporting edge (no "
        "overhang a finger can push up on), the class the planner fails on:",
        "",
    ]
    body += table(
        ["suite", "tippable with no face turned down", "of them lifted", "failures among them"],
        list(_no_face_down(plans)),
        align="lrrr",
    )
    fails = [r for r in plans if r["tippable"] and not _lifted(r)]
    reasons = Counter((r["suite"], _reason(r)) for r in fails)
    if reasons:
        body += ["", "Tippable shapes not lifted, by reason:", ""]
        body += table(
            ["suite", "reason", "shapes"],
            [[s, reason, n] for (s, reason), n in sorted(reasons.items())],
            align="llr",
        )
    if episodes:
        body += [
            "",
            "The scripted policy through the env on the same shapes (its success: form "
            "closure off the support at the episode's last step; the env's suites only):",
            "",
        ]
        env_rows = []
        for suite, mine in _by_suite(episodes):
            tippable = {r["k"] for r in plans if r["suite"] == suite and r["tippable"]}
            on_tippable = [e for e in mine if e["k"] in tippable]
            env_rows.append(
                [
                    suite,
                    _wilson(sum(e["success"] for e in mine), len(mine)),
                    _wilson(sum(e["success"] for e in on_tippable), len(on_tippable)),
                    sum(bool(e["error"]) for e in mine),
                ]
            )
        body += table(["suite", "success", "success on tippable", "errors"], env_rows, "lllr")
    if fails:
        body += ["", "Every tippable shape not lifted:", ""]
        body += table(
            ["suite", "k", "vertices", "status", "reason", "CPU (s)"],
            [
                [r["suite"], r["k"], r["vertices"], r["status"], r["reason"], f"{r['cpu']:.1f}"]
                for r in fails
            ],
            align="lrrllr",
        )
    return body


def run(
    out: Path,
    shapes: int = 200,
    suites: tuple[str, ...] = SUITES,
    env: bool = False,
    timeout: float = 120.0,
    workers: int = 2,
) -> Path:
    """Plan ``shapes`` shapes of each suite (and run the scripted policy on them with
    ``env``), ``workers`` processes at a time; write the page."""
    jobs = [("plan", s, k, timeout) for s in suites for k in range(shapes)]
    if env:
        jobs += [("env", s, k, timeout) for s in suites if s in ENV_SUITES for k in range(shapes)]
    with ProcessPoolExecutor(workers, initializer=headless) as pool:
        results = list(pool.map(_job, jobs, chunksize=1))
    plans, episodes = results[: len(suites) * shapes], results[len(suites) * shapes :]
    return write(out, "Scripted planner on random shapes", report(plans, episodes, timeout))


def main(argv: list[str] | None = None) -> int:
    ap = parser("benchmarks.planner_shapes", __doc__, "planner_shapes.md")
    ap.add_argument("--shapes", type=positive_int, default=200, help="shapes a suite")
    ap.add_argument(
        "--suites", nargs="+", choices=SUITES, default=list(SUITES),
        help="random shapes on the fig13 hand: heldout (the env's ranges, agents.evaluate's "
        "held-out shapes), wide (3-12 vertices, aspect to 1:5), small (3-5 vertices, 0.15-0.6 "
        "palm widths wide, where the planner fails)",
    )  # fmt: skip
    ap.add_argument("--env", action="store_true", help="also the scripted policy in the env")
    ap.add_argument("--timeout", type=seconds, default=120.0, help="wall seconds a plan or episode")
    ap.add_argument("--workers", type=workers, default=2, help="processes")
    args = ap.parse_args(argv)
    page = run(args.out, args.shapes, tuple(args.suites), args.env, args.timeout, args.workers)
    print(page.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
