"""The compiled core's packaging: where its machine code is cached, and the fallback to
compiling in memory where no cache folder can be written (a read-only install)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from grasp_env import compiled


def test_cache_is_used_where_it_can_be_written(tmp_path: Path) -> None:
    """The package's own folder is writable here (unless ``NUMBA_CACHE_DIR`` is set), and
    any folder numba can write to counts."""
    if "NUMBA_CACHE_DIR" not in os.environ:
        root = Path(compiled.__file__).parent
        for name, folder in compiled.CACHE_FOLDERS.items():
            assert folder == root / name / "__pycache__"
    assert compiled.CACHE
    module = tmp_path / "module.py"
    module.write_text("")
    assert compiled.cache_folder(module) is not None


def test_no_writable_cache_folder_means_compiling_in_memory() -> None:
    """A source file whose folder, user cache folder and ``NUMBA_CACHE_DIR`` cannot be
    written (paths under /proc, which not even root can create folders in): no cache, so
    the kernels are compiled in memory rather than failing at import as numba's
    ``cache=True`` does."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = "/proc/1/no-cache"  # numba's user-wide cache folder
    env["HOME"] = "/proc/1/no-home"
    code = (
        "from pathlib import Path; from grasp_env import compiled; "
        "print(compiled.cache_folder(Path('/proc/1/no-package/module.py')))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "None"


def _one_round_clear(sim, q, h0, dh) -> bool:
    """The skip test in one round: every hand body's separating distance at the start
    exceeds how far its vertices move plus the detection margin."""
    from grasp_env.sim.clearance import separation
    from grasp_env.sim.hand import vertex_speeds
    from grasp_env.sim.placement import place

    model = sim.model
    world = place(model, q, h0)
    travel = vertex_speeds(model, dh)
    return all(
        separation(world, model.n_object, model.n_vertices, b) > travel[b - 1] + 10 * model.tol
        for b in (1, 2, 3)
    )


@pytest.mark.parametrize(
    ("scene", "amplitude", "least_skipped", "least_in_rounds"),
    [
        ("fig13", (0.02, 0.02, 0.05, 0.3, 0.3), 150, 20),
        ("fig13", (0.3, 0.3, 0.3, 1.2, 1.2), 80, 20),  # long moves, some touching the object
        ("tall_rectangle", (0.3, 0.3, 0.3, 1.2, 1.2), 80, 20),
    ],
)
def test_moves_that_leave_the_object_alone_skip_the_loop_exactly(
    scene, amplitude, least_skipped, least_in_rounds
) -> None:
    """A move whose hand stays clear of an object resting on the support skips the move
    loop and keeps the old contacts; the loop (forced by not passing the known contacts)
    gives the same pose, hand and contacts for the same moves. Long moves that pass near the
    object are cleared by conservative advancement in several rounds where one bound over
    the whole move cannot clear them; moves the loop finds touching are never skipped."""
    from grasp_env import Simulator
    from grasp_env.errors import WorkLimitError
    from grasp_env.sim import move

    sim = Simulator(scene)
    start = sim.reset()
    assert {c.body for c in start.contacts} == {"support"}
    known = np.array([c.key for c in start.contacts], dtype=np.int64)
    q0, h0 = start.object_pose.copy(), start.hand.copy()  # the core takes writeable arrays
    rng = np.random.default_rng(3)
    skipped = in_rounds = 0
    for _ in range(200):
        h1 = start.hand + rng.uniform(-1, 1, 5) * np.array(amplitude)
        sim._solves[0] = 0  # each move has its own budget, as Simulator.move_arrays gives it
        fast, _, _, _ = move.run(sim.model, q0, h0, h1, known, True, sim._solves)
        sim._solves[0] = 0
        try:
            loop, events, keys, rows = move.run(sim.model, q0, h0, h1, known, False, sim._solves)
        except WorkLimitError:  # a long move pushing the object about, over the budget
            assert not fast[move.OUT_UNTOUCHED]
            continue
        assert not loop[move.OUT_UNTOUCHED]
        np.testing.assert_array_equal(fast[move.OUT_Q], loop[move.OUT_Q])
        np.testing.assert_array_equal(fast[move.OUT_H], loop[move.OUT_H])
        if fast[move.OUT_UNTOUCHED]:
            skipped += 1
            assert not events
            np.testing.assert_array_equal(keys, known)
            np.testing.assert_array_equal(
                rows[:, move.ROW_FORCE], [c.force for c in start.contacts]
            )
            np.testing.assert_array_equal(rows[:, move.ROW_GAP], [c.gap for c in start.contacts])
            dh = (h1 - start.hand) * fast[move.OUT_S_END]
            in_rounds += not _one_round_clear(sim, q0, h0, dh)
    assert skipped >= least_skipped, skipped
    assert in_rounds >= least_in_rounds, in_rounds


def test_a_model_crosses_into_compiled_code_unchanged() -> None:
    """``pack`` then the compiled ``unpack`` give back every field of the model, with the
    same types (so the same compiled code runs for both)."""
    from grasp_env import Simulator
    from grasp_env.sim.model import FIELDS, pack, unpack

    for kwargs in ({}, {"lp_solver": "highs", "max_solves": 7, "max_iterations": 123}):
        model = Simulator("tall_rectangle", **kwargs).model
        back = unpack(*pack(model))
        for name in FIELDS:
            value, got = getattr(model, name), getattr(back, name)
            assert type(value) is type(got) or isinstance(value, float | np.floating), name
            np.testing.assert_array_equal(got, value, err_msg=name)


def test_placing_the_object_alone_moves_only_its_rows() -> None:
    """Newton's iterations place the object alone (``object_points_into``) on a placement
    of every body: the result is every body placed afresh at the new pose, bit for bit, and
    the object's rows are its polygon turned and moved (numpy, the reference)."""
    from grasp_env import Simulator
    from grasp_env.sim.placement import object_points_into, world_points

    rng = np.random.default_rng(12)
    for scene in ("fig13", "triangle", "hexagon"):
        model = Simulator(scene).model
        args = (model.points, model.body, model.n_vertices, model.half)
        n, nv = model.n_object, model.n_vertices
        for _ in range(50):
            h = np.array([0.1, 0.8, 0.2, 0.5, -0.5]) + rng.normal(size=5) * 0.3
            q0, q1 = rng.normal(size=3), rng.normal(size=3)
            world = world_points(*args, q0, h)
            object_points_into(model.points, n, nv, q1, world)
            np.testing.assert_array_equal(world, world_points(*args, q1, h))
            c, si = np.cos(q1[2]), np.sin(q1[2])
            R = np.array([[c, -si], [si, c]])
            vertices, normals = model.points[:n], model.points[nv : nv + n]
            np.testing.assert_allclose(world[:n], vertices @ R.T + q1[:2], atol=1e-12)
            np.testing.assert_allclose(world[nv : nv + n], normals @ R.T, atol=1e-12)


def test_contact_velocities_match_the_reference() -> None:
    """The compiled ``xi`` (eq. 20) of hand-body contacts equals
    :func:`grasp_env.mechanics.closure.xi`, the reference, for random hand motions, points and
    normals, on every body (zero on the support)."""
    from grasp_env import Simulator
    from grasp_env.mechanics import closure as mechanics
    from grasp_env.sim.hand import contact_xi

    sim = Simulator("fig13")
    rng = np.random.default_rng(11)
    for _ in range(200):
        h = sim.scene.initial_hand + rng.normal(size=5) * 0.3
        dh = rng.normal(size=5)
        bodies = rng.integers(0, 4, size=6)
        keys = np.zeros((6, 4), dtype=np.int64)
        keys[:, 0] = bodies
        P = rng.normal(size=(6, 2))
        N = rng.normal(size=(6, 2))
        N /= np.linalg.norm(N, axis=1)[:, None]
        got = contact_xi(sim.model, h, dh, keys, P, N)
        want = mechanics.xi(sim.scene, h, dh, bodies, P, N)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_lowest_hand_point_matches_the_hand_polygons() -> None:
    """The compiled lowest hand vertex equals the lowest vertex of
    :func:`grasp_env.core.kinematics.hand_polygons_W`, the reference, for random hands."""
    from grasp_env import Simulator
    from grasp_env.core import kinematics
    from grasp_env.sim.hand import lowest_point

    sim = Simulator("tall_rectangle")
    rng = np.random.default_rng(5)
    for _ in range(200):
        h = sim.scene.initial_hand + rng.normal(size=5) * 0.5
        want = min(float(p[:, 1].min()) for p in kinematics.hand_polygons_W(sim.scene, h))
        assert abs(lowest_point(sim.model, h) - want) <= 1e-14
