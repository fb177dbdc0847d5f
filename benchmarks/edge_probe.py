"""Random steps at the edges of what the env accepts, every state checked independently.

Families of shapes and set-ups that the default tests and the soak draw rarely or not at
all, each a few shapes of random palm-control actions (biased to closing the fingers), the
state after every step checked by :func:`grasp_env.testing.check_state` and the observation
against its space, as the soak does (:func:`benchmarks.soak.run_env`):

* ``hull``: convex hulls of 6-20 random points, 0.1-0.6 palm widths across;
* ``sliver``: rectangles of aspect 1:40, 0.2-0.6 w long, on a long side;
* ``30-gon``: near-regular 30-gons (vertices 1e-3 of the radius off the circle);
* ``bulge``: a hull whose resting edge has a vertex added 1e-11 to 1e-8 w below its line
  (the object rests on that vertex);
* ``tiny``: hulls 0.05 w across;
* ``wide``: random shapes wider than the opening between the hanging fingers (1.0-1.3 w,
  in the hand set-up the env fits to each);
* ``density``: densities at the ends of the accepted range (1e-9 and 1e9; no torque
  limits, which are bounded relative to the weight);
* ``touching``: hulls placed flush against finger 1's palmar edge at the start;
* ``scaled``: the lifting task's random shapes at palm widths 1e-5 and 1e5;
* ``ids``: the three registered env ids as registered.

Usage: ``python -m benchmarks.edge_probe [--shapes N] [--steps N] [--seed S]``; the page goes
to ``runs/benchmarks/edge_probe.md`` unless ``--out`` says otherwise.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import ConvexHull

from benchmarks.common import headless, parser, table, write
from benchmarks.soak import new_record, run_env
from benchmarks.soak_shapes import rest_on_stable_edge, stress_scene
from grasp_env.cli import positive_int, seed_int

FAMILIES = (
    "hull", "sliver", "30-gon", "bulge", "tiny", "wide", "density", "touching", "scaled", "ids",
)  # fmt: skip


def hull(rng: np.random.Generator, size: float, points: int | None = None) -> np.ndarray:
    """A random convex polygon ``size`` palm widths across, resting on its most stable edge."""
    for _ in range(100):
        p = rng.uniform(-0.5, 0.5, (points or int(rng.integers(6, 21)), 2))
        v = p[ConvexHull(p).vertices]
        v = v * (size / np.ptp(v, axis=0).max())
        lengths = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
        if lengths.min() > 1e-3 * size:  # no edge the scene schema would call a vertex
            return rest_on_stable_edge(v)
    raise RuntimeError("no random hull with edges long enough")


def polygon_of(family: str, rng: np.random.Generator) -> tuple[np.ndarray, dict[str, Any]]:
    """A polygon (resting on y = 0, centroid at x = 0) of a family, and the scene's mass
    keyword (``mass`` or ``density``)."""
    mass: dict[str, Any] = {"mass": float(rng.uniform(0.05, 0.5))}
    if family == "sliver":
        length = rng.uniform(0.2, 0.6)
        v = np.array([[-0.5, 0.0], [0.5, 0.0], [0.5, 1 / 40], [-0.5, 1 / 40]]) * length
        return v, mass
    if family == "30-gon":
        angles = np.linspace(0, 2 * np.pi, 30, endpoint=False) + rng.uniform(0, 0.2)
        radius = rng.uniform(0.1, 0.25) * (1 + 1e-3 * rng.uniform(-1, 1, 30))
        v = np.column_stack([np.cos(angles), np.sin(angles)]) * radius[:, None]
        return rest_on_stable_edge(v[ConvexHull(v).vertices]), mass
    if family == "bulge":
        v = hull(rng, rng.uniform(0.15, 0.5))
        drop = 10 ** rng.uniform(-11, -8)
        middle = 0.5 * (v[0] + v[1]) - np.array([0.0, drop])
        return np.vstack([v[:1], middle, v[1:]]) + np.array([0.0, drop]), mass
    if family == "tiny":
        return hull(rng, 0.05), mass
    if family == "density":
        return hull(rng, rng.uniform(0.15, 0.5)), {"density": float(rng.choice([1e-9, 1e9]))}
    return hull(rng, rng.uniform(0.1, 0.6)), mass


def scaled_fig13(k: float) -> dict[str, Any]:
    """fig13 with every length times ``k`` (densities kept, torque limits times ``k**3``)."""
    import grasp_env
    from grasp_env.core.scene_loading import scaled_scene_dict
    from grasp_env.envs.shapes import scene_to_dict

    return scaled_scene_dict(scene_to_dict(grasp_env.load_scene("fig13")), k)


def make_env(family: str, rng: np.random.Generator):
    """An env of the family (palm control, a random start)."""
    import gymnasium as gym

    from grasp_env.envs import ENV_KWARGS
    from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv

    start = str(rng.choice(["scene", "preliftoff", "random"]))
    if family == "ids":
        env_id = str(rng.choice(list(ENV_KWARGS)))
        return gym.make(env_id), env_id
    if family == "scaled":
        k = float(rng.choice([1e-5, 1e5]))
        kwargs = {**ENV_KWARGS["FrictionlessGraspLift-v0"], "scene": scaled_fig13(k)}
        return FrictionlessGraspEnv(**kwargs), f"lifting at palm width {k:g}"
    if family == "wide":
        ranges = {"size": (1.0, 1.3), "vertices": (3, 12)}
        env = FrictionlessGraspEnv(shape_randomizer=ranges, palm_control=True, start=start)
        return env, f"start {start}"
    polygon, mass = polygon_of(family, rng)
    x0 = 0.0
    if family == "touching":  # flush against finger 1's palmar edge (x = -w/2)
        x0 = -0.5 - float(polygon[:, 0].min())
        start = "scene"
    d = stress_scene(polygon, x0=x0, **mass)
    if family == "density":
        for f in d["fingers"]:
            f["torque_limits"] = [-math.inf, math.inf]
    if family == "touching":
        d["palm"]["pose"][0] = 0.0  # the fingers hang at -+ w/2
    kwargs = {"max_vertices": 32} if family == "30-gon" else {}
    env = FrictionlessGraspEnv(scene=d, palm_control=True, start=start, **kwargs)
    return env, f"{len(polygon)} vertices, start {start}"


def probe(family: str, index: int, seed: int, steps: int) -> dict[str, Any]:
    """One shape (or set-up) of a family: its record (:func:`benchmarks.soak.new_record`)."""
    rng = np.random.default_rng([seed, FAMILIES.index(family), index])
    rec = new_record(index)
    rec["family"] = family
    t0 = time.perf_counter()
    try:
        env, rec["kind"] = make_env(family, rng)
    except Exception as exc:  # a valid scene must always make an env
        rec["exceptions"] += 1
        rec["examples"].append(f"env construction: {exc!r}")
        return rec
    run_env(env, rng, steps, rec)
    rec["time"] = time.perf_counter() - t0
    return rec


def run(shapes: int, steps: int, seed: int, out: Path) -> Path:
    """Probe every family and write the page."""
    headless()
    rows, failures = [], []
    for family in FAMILIES:
        recs = [probe(family, i, seed, steps) for i in range(shapes)]
        total = {k: sum(r[k] for r in recs) for k in ("steps", "exceptions", "sim_errors")}
        violating = sum(r["violating_steps"] for r in recs)
        worst = max(r["residual"] for r in recs)
        rows.append([
            family, shapes, total["steps"], total["exceptions"], total["sim_errors"], violating,
            f"{max(r['penetration'] for r in recs):.2e}", f"{worst:.2e}",
            f"{min(r['descent'] for r in recs):.2e}", sum(r["wedged"] for r in recs),
        ])  # fmt: skip
        for r in recs:
            if r["exceptions"] or r["sim_errors"] or r["violating_steps"]:
                failures.append(f"- {family} {r['index']} ({r.get('kind', '')}): " + "; ".join(
                    e.splitlines()[0] for e in r["examples"]))  # fmt: skip
        print(f"{family}: {total}, violating steps {violating}")
    body = [
        f"`python -m benchmarks.edge_probe --shapes {shapes} --steps {steps} --seed {seed}`: "
        "random palm-control steps on each family of the module docstring, every state "
        "checked by `grasp_env.testing.check_state` (penetration and gaps in palm widths, "
        "residual and descent in weights, of the states held at first order; wedged steps: "
        "every descent blocked at second order).",
        "",
        *table(
            [
                "family",
                "shapes",
                "steps",
                "exceptions",
                "sim errors",
                "violating steps",
                "worst penetration",
                "worst residual",
                "most negative descent",
                "wedged steps",
            ],
            rows,
        ),
        "",
        "Failures (reproduce with `benchmarks.edge_probe.probe(family, index, seed, steps)`):",
        "",
        *(failures or ["- none"]),
    ]
    return write(out, "Edge probe", body)


def main(argv: list[str] | None = None) -> int:
    ap = parser("benchmarks.edge_probe", __doc__, "edge_probe.md")
    ap.add_argument("--shapes", type=positive_int, default=10, help="shapes per family")
    ap.add_argument("--steps", type=positive_int, default=300, help="steps per shape")
    ap.add_argument("--seed", type=seed_int, default=0, help="seed")
    args = ap.parse_args(argv)
    run(args.shapes, args.steps, args.seed, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
