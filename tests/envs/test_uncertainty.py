"""The env's ``uncertainty``: the simulated object is the nominal one perturbed at every
reset, the observation's shape features show the nominal one.

Checked against the drawn perturbation's statistics, the scene's geometry (convexity, rest on
the support, clearance of the hand), distances computed here from the hand's polygons, and
the env without the argument (to the bit at ``uncertainty=0``).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from vector_checks import lockstep

import grasp_env
from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.envs.checks import placement_problem
from grasp_env.envs.shapes import scene_to_dict
from grasp_env.envs.uncertainty import MAX_PERTURBATION_TRIES, perturbed_scene
from grasp_env.kernel.observation import POSE_ENTRIES, hand_block_at

SIGMA = 0.01


def perturbations(env, seeds) -> list[tuple]:
    """``(simulated scene, nominal scene)`` at each seeded reset."""
    out = []
    for seed in seeds:
        env.reset(seed=seed)
        out.append((env.unwrapped.scene, env.unwrapped.nominal_scene))
    return out


def polygon_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between two disjoint polygons: the least distance between their edges."""
    edges = [
        (p, q) for poly in (a, b) for p, q in zip(poly, np.roll(poly, -1, axis=0), strict=True)
    ]
    na = len(a)
    return min(
        geo.segment_distance(*edges[i], *edges[na + j]) for i in range(na) for j in range(len(b))
    )


def test_the_vertices_move_by_normal_noise_of_the_given_deviation() -> None:
    env = gym.make("FrictionlessGrasp-v0", uncertainty=SIGMA)
    free, resting_y = [], []
    for true, nominal in perturbations(env, range(150)):
        noise = true.object.vertices_W0 - nominal.object.vertices_W0
        on_support = nominal.object.vertices_W0[:, 1] == 0.0
        resting_y += noise[on_support, 1].tolist()
        free += noise[:, 0].tolist() + noise[~on_support, 1].tolist()
    free = np.array(free) / true.palm.width
    assert np.abs(resting_y).max() < 1e-15  # the resting edge moves along the support only
    assert abs(free.std() / SIGMA - 1.0) < 0.06
    assert abs(free.mean()) < 4 * SIGMA / math.sqrt(len(free))


def test_the_simulated_object_is_convex_and_rests_on_the_support_clear_of_the_hand() -> None:
    env = gym.make("FrictionlessGrasp-v0", uncertainty=0.02)
    for true, nominal in perturbations(env, range(40)):
        v = true.object.vertices_W0
        assert geo.is_convex_ccw(v) and geo.turns_once(v)
        resting = nominal.object.vertices_W0[:, 1] == 0.0
        assert np.all(v[resting, 1] == 0.0) and np.all(v[~resting, 1] > 0.0)
        assert v[resting, 0].min() < true.object.start_pose[0] < v[resting, 0].max()
        assert placement_problem(true, true.object.start_pose, true.initial_hand, 1e-9) is None
        assert np.array_equal(true.initial_hand, nominal.initial_hand)
        assert not np.array_equal(v, nominal.object.vertices_W0)
    state = env.unwrapped.state
    assert state.scene is env.unwrapped.scene
    np.testing.assert_array_equal(state.object_pose, env.unwrapped.scene.object.start_pose)


def test_the_observation_shows_the_nominal_vertices() -> None:
    env = gym.make("FrictionlessGrasp-v0", uncertainty=SIGMA)
    obs, _ = env.reset(seed=3)
    base = env.unwrapped
    n = len(base.nominal_scene.object.vertices_B)
    block = obs[POSE_ENTRIES : POSE_ENTRIES + 2 * n]
    nominal = (base.nominal_scene.object.vertices_B / base.scene.palm.width).ravel()
    np.testing.assert_array_equal(block, nominal.astype(np.float32))
    assert not np.array_equal(block, base.scene.object.vertices_B.ravel().astype(np.float32))
    plain, _ = gym.make("FrictionlessGrasp-v0").reset(seed=3)
    np.testing.assert_array_equal(obs[POSE_ENTRIES : POSE_ENTRIES + 3 * 12], plain[13:49])


def test_the_hand_distances_are_to_the_nominal_object_at_the_simulated_pose() -> None:
    env = gym.make("FrictionlessGraspLift-v0", uncertainty=0.02)
    base = env.unwrapped
    at = hand_block_at(base.max_vertices) + 4  # palm, finger 1, finger 2
    compared = 0
    for seed in range(6):
        obs, _ = env.reset(seed=seed)
        for _ in range(3):
            state = base.state
            hand = kin.hand_polygons_W(base.scene, state.hand)
            nominal = geo.transform(state.object_pose, base.nominal_scene.object.vertices_B)
            true = geo.transform(state.object_pose, base.scene.object.vertices_B)
            w = base.scene.palm.width
            for b in range(3):
                d_nominal = polygon_distance(nominal, hand[b])
                if obs[at + b] > 1e-6 and d_nominal > 1e-6:
                    assert obs[at + b] == pytest.approx(d_nominal / w, rel=1e-5, abs=1e-6)
                    assert abs(polygon_distance(true, hand[b]) - d_nominal) > 1e-6
                    compared += 1
            obs = env.step(np.array([1.0, 1.0, 0.0, 0.0, 0.0]))[0]
    assert compared > 0


def test_a_seed_gives_the_same_perturbation_and_another_seed_another() -> None:
    first, second = (
        gym.make("FrictionlessGrasp-v0", uncertainty=SIGMA),
        gym.make("FrictionlessGrasp-v0", uncertainty=SIGMA),
    )
    (a, _), (b, _), (c, _) = perturbations(first, [7, 8]) + perturbations(second, [7])
    np.testing.assert_array_equal(a.object.vertices_W0, c.object.vertices_W0)
    assert not np.array_equal(a.object.vertices_W0, b.object.vertices_W0)


@pytest.mark.parametrize("env_id", ["FrictionlessGrasp-v0", "FrictionlessGraspLift-v0"])
@pytest.mark.parametrize("zero", [0.0, 0, {"vertices": 0.0, "mass": 0.0}])
def test_at_zero_the_env_is_the_env_without_the_argument(env_id: str, zero) -> None:
    plain, zeroed = gym.make(env_id), gym.make(env_id, uncertainty=zero)
    rng = np.random.default_rng(0)
    for seed in (0, None):
        a, info_a = plain.reset(seed=seed)
        b, info_b = zeroed.reset(seed=seed)
        np.testing.assert_array_equal(a, b)
        assert zeroed.unwrapped.nominal_scene is zeroed.unwrapped.scene
        for _ in range(25):
            action = np.abs(rng.uniform(-1, 1, plain.action_space.shape)).astype(np.float32)
            a, ra, ta, ua, info_a = plain.step(action)
            b, rb, tb, ub, info_b = zeroed.step(action)
            np.testing.assert_array_equal(a, b)
            assert (ra, ta, ua) == (rb, tb, ub)
            np.testing.assert_array_equal(info_a["object_pose"], info_b["object_pose"])
            if ta or ua:
                break
    state = plain.unwrapped.np_random.bit_generator.state
    assert state == zeroed.unwrapped.np_random.bit_generator.state  # nothing more drawn


def test_the_mass_is_scaled_by_normal_noise_and_the_vertices_kept() -> None:
    env = gym.make("FrictionlessGrasp-v0", uncertainty={"mass": 0.1})
    ratios = []
    for true, nominal in perturbations(env, range(200)):
        np.testing.assert_array_equal(true.object.vertices_W0, nominal.object.vertices_W0)
        ratios.append(true.object.mass / nominal.object.mass)
    assert abs(np.mean(ratios) - 1.0) < 4 * 0.1 / math.sqrt(len(ratios))
    assert abs(np.std(ratios) / 0.1 - 1.0) < 0.15


def test_the_batched_env_perturbs_as_the_single_one() -> None:
    """Sub-env i of ``make_vec`` with uncertainty follows a single env reset with seed + i."""
    steps = lockstep("FrictionlessGraspLift-v0", 3, 40, uncertainty=0.02, time_limit=25)
    assert sum(ended for *_, ended in steps) > 0


@pytest.mark.parametrize("bad", [-0.01, math.nan, math.inf, 2.0, {"vertices": -1.0}])
def test_a_bad_uncertainty_is_refused_by_name(bad) -> None:
    with pytest.raises(ValueError, match=r"uncertainty.*must be.*got"):
        gym.make("FrictionlessGrasp-v0", uncertainty=bad)


@pytest.mark.parametrize("bad", ["0.01", None, True, {"mass": "x"}])
def test_an_uncertainty_that_is_not_a_number_is_refused_by_name(bad) -> None:
    with pytest.raises(TypeError, match=r"uncertainty.*must be a number, got"):
        gym.make("FrictionlessGrasp-v0", uncertainty=bad)


def test_an_unknown_key_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"uncertainty: unknown key\(s\) \['com'\]"):
        gym.make("FrictionlessGrasp-v0", uncertainty={"com": 0.01})


def test_a_scene_no_perturbation_fits_is_refused_at_make() -> None:
    with pytest.raises(ValueError, match=rf"uncertainty.*out of {MAX_PERTURBATION_TRIES}"):
        gym.make("FrictionlessGrasp-v0", uncertainty=1.0)


def test_a_vertex_moved_inside_the_others_is_dropped_from_the_hull() -> None:
    """A small octagon (vertices 0.03 palm widths apart) at 0.02: the moved vertices often
    leave convex position, and the object is their convex hull, checked independently: its
    vertices are moved vertices, and every moved vertex lies in it."""
    angles = np.linspace(0.0, 2.0 * np.pi, 9)[:-1] - np.pi / 8.0
    octagon = 0.04 * np.c_[np.cos(angles), np.sin(angles)]
    octagon[:, 1] -= octagon[:, 1].min()
    octagon[np.abs(octagon[:, 1]) < 1e-15, 1] = 0.0
    scene = grasp_env.load_scene(
        {**scene_to_dict(grasp_env.load_scene("fig13")), "object": {"vertices": octagon.tolist()}}
    )
    nominal = scene.object.vertices_W0
    resting = nominal[:, 1] == 0.0
    dropped = 0
    for seed in range(40):
        out = perturbed_scene(np.random.default_rng(seed), scene, {"vertices": 0.02, "mass": 0.0})
        noise = np.random.default_rng(seed).normal(0.0, 0.02, nominal.shape)  # the first draw
        noise[resting, 1] = 0.0
        moved = nominal + noise
        v = out.object.vertices_W0
        if len(v) == len(nominal) and np.array_equal(v, moved):
            continue  # the first draw was convex: kept as drawn, in its order
        if not all(any(np.array_equal(p, q) for q in moved) for p in v):
            continue  # the first draw was refused for another reason and redrawn
        dropped += 1
        assert len(v) < len(nominal) and geo.is_convex_ccw(v)
        edges = np.roll(v, -1, axis=0) - v
        for p in moved:  # inside or on every edge of the counter-clockwise hull
            cross = edges[:, 0] * (p - v)[:, 1] - edges[:, 1] * (p - v)[:, 0]
            assert np.all(cross >= -1e-15)
    assert dropped >= 5
