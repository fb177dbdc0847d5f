"""Refusals show the refused value exactly: a value one float past a bound appears in the
message as its ``repr`` (e.g. ``1000000000.0000001``), not rounded onto the bound it
oversteps. Covers scene loading, the argument checks and the env's keyword arguments and
reset options."""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import grasp_env
from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin
from grasp_env.core.scene import DEFAULT_CONTACT_TOL
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.errors import SceneError

SCENES_DIR = Path(grasp_env.__file__).resolve().parent / "scenes"
INF = math.inf


def fig13() -> dict:
    return yaml.safe_load((SCENES_DIR / "fig13.yaml").read_text())


def with_value(path: tuple, value: Any, d: dict | None = None) -> dict:
    """fig13 (or ``d``) with the field at ``path`` set to ``value``."""
    d = copy.deepcopy(fig13() if d is None else d)
    node = d
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return d


def refusal(call) -> str:
    with pytest.raises((ValueError, TypeError)) as info:
        call()
    return str(info.value)


def just_past(bound: float, direction: float) -> float:
    return float(np.nextafter(bound, direction))


@pytest.mark.parametrize(
    ("path", "value"),
    [
        (("object", "density"), just_past(1e9, INF)),
        (("palm", "density"), just_past(1e-9, 0.0)),
        (("palm", "width"), just_past(1e6, INF)),
        (("gravity",), just_past(1e9, INF)),
        (("fingers", 0, "length"), just_past(1e3, INF)),  # LENGTH_RANGE palm widths (w = 1)
    ],
    ids=["object-density", "palm-density", "palm-width", "gravity", "finger-length"],
)
def test_scene_field_just_past_its_range_is_shown_exactly(path: tuple, value: float) -> None:
    msg = refusal(lambda: grasp_env.load_scene(with_value(path, value)))
    assert repr(value) in msg, msg
    assert str(path[-1]) in msg


def test_mean_density_just_past_its_range_is_shown_exactly() -> None:
    """An object given by its mass: the mean density it implies (mass / area), one float past
    ``1e9``, is shown exactly, not as the ``1e+09`` it rounds to."""
    d = fig13()
    area = geo.polygon_area(np.array(d["object"]["vertices"], dtype=float))
    mass = 1e9 * area
    while not mass / area > 1e9:
        mass = float(np.nextafter(mass, INF))
    assert f"{mass / area:g}" == "1e+09"  # what a rounded message would show
    del d["object"]["density"]
    d["object"]["mass"] = mass
    with pytest.raises(SceneError) as info:
        grasp_env.load_scene(d)
    msg = str(info.value)
    assert "object.mass" in msg and "mean density" in msg
    assert repr(mass / area) in msg and repr(mass) in msg, msg


@pytest.mark.parametrize(
    ("kwargs", "value"),
    [
        ({"gamma": just_past(1.0, INF)}, just_past(1.0, INF)),
        ({"contact_tol": just_past(1e-11, 0.0)}, just_past(1e-11, 0.0)),
        ({"max_finger_step": just_past(math.pi / 2, INF)}, just_past(math.pi / 2, INF)),
        (
            {"shape_randomizer": {"size": (0.2, just_past(1e3, INF))}},
            just_past(1e3, INF),
        ),
    ],
    ids=["gamma", "contact_tol", "max_finger_step", "shape_size"],
)
def test_env_kwarg_just_past_its_range_is_shown_exactly(kwargs: dict, value: float) -> None:
    msg = refusal(lambda: FrictionlessGraspEnv(**kwargs))
    assert repr(value) in msg, msg
    assert next(iter(kwargs)) in msg


def test_palm_option_just_outside_the_workspace_is_shown_exactly() -> None:
    """A palm x one float beyond the workspace (x0 +- 2 palm widths)."""
    env = FrictionlessGraspEnv()
    env.reset(seed=0)
    scene = env.unwrapped.scene
    x0 = float(scene.object.start_pose[0])
    x = x0 + 2.0 * scene.palm.width
    while not abs(x - x0) > 2.0 * scene.palm.width:
        x = float(np.nextafter(x, INF))
    palm = (x, float(scene.palm.pose[1]), 0.0)
    msg = refusal(lambda: env.reset(options={"palm": palm}))
    assert "options['palm']" in msg and "palm workspace" in msg
    assert repr(x) in msg and repr(abs(x - x0)) in msg and repr(x0) in msg, msg


def test_overlap_just_past_the_tolerance_is_shown_exactly() -> None:
    """The object one float more than the contact tolerance into the support: the placement
    check shows its lowest y exactly."""
    scene = grasp_env.load_scene("fig13")
    tol = DEFAULT_CONTACT_TOL * scene.palm.width
    pose = scene.object.start_pose.copy()
    pose[1] -= tol
    while not geo.transform(pose, scene.object.vertices_B)[:, 1].min() < -tol:
        pose[1] = np.nextafter(pose[1], -INF)
    lowest = float(geo.transform(pose, scene.object.vertices_B)[:, 1].min())
    msg = kin.hand_placement_problem(scene, pose, scene.initial_hand, tol)
    assert msg is not None and repr(lowest) in msg, msg


def test_hand_overlap_refused_by_a_reset_option_is_shown_exactly() -> None:
    """The palm lowered into the object's top, fingers spread: the env's refusal shows the
    overlap (0.05 palm widths, up to rounding) as a float at full precision."""
    env = FrictionlessGraspEnv()
    env.reset(seed=0)
    scene = env.unwrapped.scene
    h = scene.initial_hand.copy()
    h[1:] = (0.35 * scene.palm.width, 0.0, -math.pi, 0.0)  # the object's top is at 0.4 w
    problem = kin.hand_placement_problem(
        scene, scene.object.start_pose, h, env.contact_tol * scene.palm.width
    )
    assert problem is not None
    assert problem.startswith("the palm overlaps the object by "), problem
    number = problem.rsplit(" ", 1)[1]
    assert repr(float(number)) == number and len(number.lstrip("-0.")) > 4, problem
    msg = refusal(lambda: env.reset(options={"palm": tuple(h[:3]), "fingers": tuple(h[3:])}))
    assert problem in msg, msg
