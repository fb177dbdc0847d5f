"""The envs at every palm width: random shapes keep their size relative to the hand, and a
scene scaled by k gives, for the same seed, the episode of the unscaled scene scaled by k.

The scene is fig13 scaled by k (every length times k, densities kept, so masses scale by
k^2; torque limits by k^3, force times length), over the accepted palm widths.
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import grasp_env
from grasp_env.core.scene_loading import scaled_scene_dict
from grasp_env.envs import ENV_KWARGS
from grasp_env.envs.shapes import DEFAULT_SHAPE_RANGES, random_shape_scene
from grasp_env.kernel import observation as obs_layout
from grasp_env.kernel.observation import FORCE_MAX

SCENES_DIR = Path(grasp_env.__file__).resolve().parent / "scenes"
#: Palm widths run: both ends of the accepted range within a decade, and between.
WIDTHS = (1e-5, 1e-2, 1.0, 1e2, 1e5)
SCALED = tuple(k for k in WIDTHS if k != 1.0)
ENV_IDS = tuple(ENV_KWARGS)
#: Vertices of a random shape at k, divided by k, against those at width 1 (relative to its
#: size): the same draws, scaled, differ only by the rounding of the scaling.
VERTEX_RTOL = 1e-12
#: Observations (float32, every entry in palm widths, object weights or radians), rewards and
#: object poses (palm widths) of the same episode at k and at width 1: where the object
#: ends a move in a fold its pose is fixed only to about the square root of the contact
#: tolerance (1e-9 palm widths); these episodes agree to 5e-7.
OBS_ATOL = 1e-5
REWARD_ATOL = 1e-5
POSE_ATOL = 1e-5


def fig13(k: float) -> dict:
    """fig13 as a dict with every length times ``k`` (densities kept: masses scale by k^2;
    torque limits by k^3)."""
    return scaled_scene_dict(yaml.safe_load((SCENES_DIR / "fig13.yaml").read_text()), k)


def size_in_palm_widths(scene: grasp_env.Scene) -> float:
    """The object's diameter (largest vertex-to-vertex distance) over the palm width."""
    v = scene.object.vertices_B
    return float(np.linalg.norm(v[:, None] - v[None], axis=2).max()) / scene.palm.width


@pytest.mark.parametrize("k", SCALED)
def test_random_shape_of_a_scaled_scene_is_the_shape_scaled(k: float) -> None:
    """The same generator state draws, at palm width k, the shape at width 1 times k: its
    vertices, its mass times k^2 and its hand set-up (palm pose times k, finger angles)."""
    base_1, base_k = grasp_env.load_scene(fig13(1.0)), grasp_env.load_scene(fig13(k))
    for seed in range(5):
        a = random_shape_scene(np.random.default_rng(seed), base_1)
        b = random_shape_scene(np.random.default_rng(seed), base_k)
        v = a.object.vertices_W0
        size = float(np.ptp(v, axis=0).max())
        np.testing.assert_allclose(b.object.vertices_W0 / k, v, rtol=0, atol=VERTEX_RTOL * size)
        assert b.object.mass / k**2 == pytest.approx(a.object.mass, rel=1e-12)
        np.testing.assert_allclose(b.palm.pose / [k, k, 1.0], a.palm.pose, rtol=1e-12)
        np.testing.assert_allclose(b.initial_hand[3:], a.initial_hand[3:], rtol=1e-12)


@pytest.mark.parametrize("k", WIDTHS)
def test_random_shapes_are_sized_in_palm_widths(k: float) -> None:
    """The default sizes (diameters of 0.2-0.45 palm widths) hold at every palm width."""
    lo, hi = DEFAULT_SHAPE_RANGES["size"]
    base = grasp_env.load_scene(fig13(k))
    rng = np.random.default_rng(1)
    for _ in range(5):
        scene = random_shape_scene(rng, base)
        assert lo * (1 - 1e-12) <= size_in_palm_widths(scene) <= hi * (1 + 1e-12)


@pytest.mark.parametrize("k", WIDTHS)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_every_env_id_runs_at_every_palm_width(env_id: str, k: float) -> None:
    """Each registered id builds, resets and steps on fig13 scaled to palm width k."""
    env = gym.make(env_id, scene=fig13(k))
    rng = np.random.default_rng(0)
    obs, info = env.reset(seed=0)
    assert "sim_error" not in info
    scene = env.unwrapped.scene
    assert scene.palm.width == k
    if env.unwrapped.shape_ranges is not None:
        lo, hi = DEFAULT_SHAPE_RANGES["size"]
        assert lo * (1 - 1e-12) <= size_in_palm_widths(scene) <= hi * (1 + 1e-12)
    for _ in range(10):
        obs, reward, terminated, truncated, info = env.step(
            rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        )
        assert env.observation_space.contains(obs)
        assert "sim_error" not in info and math.isfinite(reward)
        if terminated or truncated:
            break
    env.close()


def _episode(env_id: str, kwargs: dict, k: float, seed: int, steps: int = 30) -> dict:
    """A seeded episode of ``env_id`` on fig13 scaled by ``k``: the fingers close for the
    first half (so that the hand meets the object), then random actions."""
    env = gym.make(env_id, scene=fig13(k), **kwargs)
    rng = np.random.default_rng(100 + seed)
    obs, info = env.reset(seed=seed)
    scene = env.unwrapped.scene
    out = {
        "vertices": scene.object.vertices_W0 / k,
        "mass": scene.object.mass / k**2,
        "obs": [obs],
        "rewards": [],
        "object_pose": [info["object_pose"] / [k, k, 1.0]],
        "grip": [],
        "errors": [info.get("sim_error")],
        "jammed": [info["jammed"]],
        "forces_at": [
            obs_layout.contact_block_at(env.unwrapped.max_vertices) + i + 1
            for i in obs_layout.BODY_INDEX.values()
        ],
    }
    weight = scene.object_weight
    for i in range(steps):
        a = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        if i < steps // 2:
            a[:2] = np.abs(a[:2])
        obs, reward, terminated, truncated, info = env.step(a)
        out["obs"].append(obs)
        out["rewards"].append(reward)
        out["object_pose"].append(info["object_pose"] / [k, k, 1.0])
        out["grip"].append(info["grip_force"] / weight)
        out["errors"].append(info.get("sim_error"))
        out["jammed"].append(info["jammed"])
        if terminated or truncated:
            break
    env.close()
    return out


#: Each id, and the starts and observation blocks the ids leave out.
EPISODE_CASES = [(env_id, {}) for env_id in ENV_IDS] + [
    ("FrictionlessGrasp-v0", {"start": "random", "palm_control": True}),
    ("FrictionlessGrasp-v0", {"start": "preliftoff", "hand_features": True}),
    ("FrictionlessGraspRandomShapes-v0", {"start": "random", "hand_features": True}),
]


@pytest.mark.parametrize("k", SCALED)
@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    EPISODE_CASES,
    ids=["-".join([e, *(f"{k}={v}" for k, v in kw.items())]) for e, kw in EPISODE_CASES],
)
def test_scaled_scene_gives_the_same_episode(env_id: str, kwargs: dict, k: float) -> None:
    """For the same seed and actions, fig13 scaled by k gives the object of width 1 scaled by
    k and the same observations (in palm widths, object weights and radians), rewards, y* / W
    and object poses (scaled by k).

    But for the contact forces of a step that ends in a jam in both: the hand then squeezes
    the object at a fold of the contact equations, where the least total force in
    equilibrium jumps between contact subsets as the normals turn concurrent (lifting from
    the placement at k = 1e5: 2.5 object weights on two of three contacts, or 5.6e6 on all
    three, for poses that differ at the contact tolerance). There the forces are checked to be
    forces (within the observation's range); the jam itself, the pose and the rest agree."""
    for seed in (0, 1):
        a = _episode(env_id, kwargs, 1.0, seed)
        b = _episode(env_id, kwargs, k, seed)
        size = float(np.ptp(a["vertices"], axis=0).max())
        np.testing.assert_allclose(b["vertices"], a["vertices"], rtol=0, atol=VERTEX_RTOL * size)
        assert b["mass"] == pytest.approx(a["mass"], rel=1e-12)
        assert b["errors"] == a["errors"] == [None] * len(a["errors"])
        assert len(b["obs"]) == len(a["obs"])
        assert b["jammed"] == a["jammed"]
        for i, (x, y) in enumerate(zip(a["obs"], b["obs"], strict=True)):
            if a["jammed"][i]:  # a jam's forces: forces, not compared (see above)
                forces = a["forces_at"]
                assert np.all((x[forces] >= 0) & (x[forces] <= FORCE_MAX))
                assert np.all((y[forces] >= 0) & (y[forces] <= FORCE_MAX))
                x, y = np.delete(x, forces), np.delete(y, forces)
            np.testing.assert_allclose(y, x, rtol=0, atol=OBS_ATOL, err_msg=f"step {i}")
        np.testing.assert_allclose(b["rewards"], a["rewards"], rtol=0, atol=REWARD_ATOL)
        np.testing.assert_allclose(b["grip"], a["grip"], rtol=1e-6)
        np.testing.assert_allclose(
            np.array(b["object_pose"]), np.array(a["object_pose"]), rtol=0, atol=POSE_ATOL
        )
