"""Short versions of the soak (benchmarks/soak.py) and the memory check.

* ``test_soak_short``: 1,000 random-action env steps on 10 random stress shapes, every step
  checked by :func:`grasp_env.testing.check_state`; nothing may raise, fail or violate an invariant.
* ``test_soak_10k`` (slow): the same over 10,000 steps and 100 shapes in two processes.
* ``test_soak_resumes``: an interrupted soak resumes from its checkpoint and gives the same
  records as an uninterrupted one.
* ``test_memory_flat_over_resets``: resident memory (``/proc/self/statm``) stays flat over
  500 resets with a new random shape and a rendered frame each (10,000 in the slow variant).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from grasp_env import testing
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import soak

from benchmarks import soak_shapes


def assert_clean(records: list[dict]) -> dict:
    s = soak.summarise(records)
    examples = [ex.splitlines()[0] for r in records for ex in r["examples"]][:5]
    assert s["exceptions"] == 0, examples
    assert s["sim_errors"] == 0, examples
    assert s["nan"] == 0, examples
    assert s["violating_steps"] == 0, (s["bad_shapes"], examples)
    assert s["penetration"] <= 1e-9 + testing.ROUNDING
    assert s["residual"] <= testing.EQ_RTOL
    return s


def test_soak_short() -> None:
    records, _ = soak.run_soak(steps=1000, shapes=10, workers=1, seed=11)
    s = assert_clean(records)
    assert s["steps"] == 1000 and s["shapes"] == 10


@pytest.mark.slow
def test_soak_10k() -> None:
    records, _ = soak.run_soak(steps=10_000, shapes=100, workers=2, seed=12)
    s = assert_clean(records)
    assert s["steps"] == 10_000 and s["shapes"] == 100


def test_soak_resumes(tmp_path: Path) -> None:
    ckpt = tmp_path / "soak.jsonl"
    full, _ = soak.run_soak(steps=60, shapes=3, workers=1, seed=13, checkpoint=ckpt)
    lines = ckpt.read_text().splitlines()
    assert len(lines) == 3
    ckpt.write_text(lines[0] + "\n")  # interrupted after the first shape
    resumed, _ = soak.run_soak(steps=60, shapes=3, workers=1, seed=13, checkpoint=ckpt)
    assert len(ckpt.read_text().splitlines()) == 3  # only the two missing shapes ran again

    def strip(r: dict) -> dict:
        return {k: v for k, v in r.items() if k != "time"}

    assert [strip(r) for r in resumed] == [strip(json.loads(json.dumps(r))) for r in full]


def test_random_stress_scenes_cover_the_ranges() -> None:
    """The soak's shapes span the stress ranges: 3..12 vertices, diameters 0.05..0.8, aspect to
    1:30, every degenerate kind, densities over six orders of magnitude."""
    import grasp_env

    rng = np.random.default_rng(0)
    kinds, sizes, densities, counts, thinness = set(), [], [], [], []
    for _ in range(300):
        d = soak_shapes.random_stress_scene(rng)
        sc = grasp_env.load_scene(d)
        v = sc.object.vertices_B
        kinds.add(d["description"])
        size = float(np.linalg.norm(v[:, None] - v[None], axis=-1).max())
        sizes.append(size)
        densities.append(d["object"]["density"])
        counts.append(len(v))
        thinness.append(float(np.ptp(v[:, 1])) / size)  # resting on its most stable edge
    assert kinds == set(soak_shapes.SCENE_KINDS)
    # "parallel" and "collinear" move a vertex by up to 1e-2 of the diameter
    assert min(sizes) < 0.1 and max(sizes) > 0.7 and max(sizes) <= 0.8 * (1 + 1e-2)
    assert min(densities) < 3e-3 and max(densities) > 300
    assert min(counts) == 3 and max(counts) == 12
    assert min(thinness) < 1 / 20


@pytest.mark.parametrize("rest", ["left", "right", "neighbours"])
def test_bulge_on_the_resting_edge(rest: str) -> None:
    """A bulge polygon has a vertex inside its resting edge, 1e-12..1e-9 outside the line
    through its neighbours: resting on it and one neighbour (the other just above the
    support), or on both neighbours (the vertex that far below the support)."""
    import grasp_env

    for seed in range(20):
        v = soak_shapes.bulge_polygon(np.random.default_rng(seed), 6, 0.4, 3.0, rest)
        a, m, b = (v[-1], v[0], v[1]) if rest == "right" else (v[0], v[1], v[2])
        d = b - a
        offset = float(d[0] * (a[1] - m[1]) - d[1] * (a[0] - m[0])) / float(np.hypot(*d))
        assert 0.99e-12 <= offset <= 1.01e-9  # outward: the polygon stays convex
        assert a[0] < m[0] < b[0]
        if rest == "neighbours":
            assert a[1] == b[1] == 0.0 and -1e-9 <= m[1] < 0.0
        else:
            assert v[0, 1] == v[1, 1] == 0.0 and v[2:, 1].min() > 0.0
        grasp_env.load_scene(soak_shapes.stress_scene(v, density=1.0))  # a valid scene


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def resets_with_rendering(n: int, warmup: int = 100) -> tuple[float, float]:
    env = FrictionlessGraspEnv("fig13", shape_randomizer=True, render_mode="rgb_array")
    before = 0.0
    for i in range(n + warmup):
        env.reset(seed=i)
        frame = env.render()
        assert frame.shape == (480, 640, 3)
        if i == warmup - 1:
            before = rss_mb()
    after = rss_mb()
    env.close()
    return before, after


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc")
def test_memory_flat_over_resets() -> None:
    before, after = resets_with_rendering(500)
    assert after - before < 2.0, f"RSS grew from {before:.1f} MB to {after:.1f} MB"


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="needs /proc")
def test_memory_flat_over_10000_resets() -> None:
    before, after = resets_with_rendering(10_000)
    assert after - before < 8.0, f"RSS grew from {before:.1f} MB to {after:.1f} MB"
