"""Bad input at every boundary of the environment: scenes, env kwargs, reset options, actions.

Each malformed input must be refused with a ``ValueError`` or ``TypeError`` whose message names
the field and shows the value. After a refused ``reset`` or ``step`` the env must keep working
exactly as if the call had not happened: a twin env that never saw the bad call, stepped
with the same actions, must give the same observations and info.
"""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv

SCENES_DIR = Path(__file__).resolve().parents[1] / "configs" / "scenes"
BASE = yaml.safe_load((SCENES_DIR / "fig13.yaml").read_text())
V = BASE["object"]["vertices"]


def changed(path: tuple, value: Any) -> dict:
    d = copy.deepcopy(BASE)
    node = d
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return d


def message_of(exc: BaseException) -> str:
    # numpy >= 2 shows scalars as np.float64(x): read them as x
    return re.sub(r"np\.float64\(([^()]*)\)", r"\1", str(exc))


# ---------------------------------------------------------------------------------------
# Cases: (id, kind, bad input, field regex, value regex)
# ---------------------------------------------------------------------------------------

SCENES = [
    ("clockwise", changed(("object", "vertices"), V[::-1]), r"object\.vertices", r"clockwise"),
    (
        "nonconvex",
        changed(("object", "vertices"), [*V[:3], [0.0, 0.1], V[4]]),
        r"object\.vertices",
        r"\[0\.0, 0\.1\]",
    ),
    (
        "overlapping_start",
        changed(("object", "vertices"), [[x + 0.2, y] for x, y in V]),
        r"fingers\[1\]",
        r"overlaps the object at the start by 0\.0\d",
    ),
    ("zero_palm_width", changed(("palm", "width"), 0.0), r"palm\.width", r"0\.0"),
    ("zero_finger_length", changed(("fingers", 0, "length"), 0), r"fingers\[0\]\.length", r"0"),
    ("unknown_key", changed(("friction",), 0.3), r"unknown key", r"'friction'"),
    (
        "nan_vertex",
        changed(("object", "vertices", 1, 0), math.nan),
        r"object\.vertices\[1\]\[0\]",
        r"nan",
    ),
    ("inf_gravity", changed(("gravity",), math.inf), r"gravity", r"inf"),
    (
        "angle_out_of_limits",
        changed(("fingers", 1, "angle"), 0.4),
        r"fingers\[1\]\.angle",
        r"0\.4",
    ),
    (
        "vertex_string",
        changed(("object", "vertices", 2), "0.33, 0.24"),
        r"object\.vertices\[2\]",
        r"'0\.33, 0\.24'",
    ),
    (
        "below_support",
        changed(("object", "vertices"), [[x, y - 0.05] for x, y in V]),
        r"object\.vertices",
        r"-0\.05",
    ),
    ("negative_density", changed(("object", "density"), -2.0), r"object\.density", r"-2\.0"),
    ("palm_pose_short", changed(("palm", "pose"), [0.0, 0.7]), r"palm\.pose", r"\[0\.0, 0\.7\]"),
    ("finger_limits_nan", changed(("fingers", 0, "limits"), [math.nan, 0.0]),
     r"fingers\[0\]\.limits", r"nan"),
    ("scene_type", 42, r"scene", r"42"),
]  # fmt: skip

KWARGS = [
    ("max_finger_step_nan", {"max_finger_step": math.nan}, r"max_finger_step", r"nan"),
    ("max_finger_step_negative", {"max_finger_step": -0.1}, r"max_finger_step", r"-0\.1"),
    ("max_finger_step_string", {"max_finger_step": "0.05"}, r"max_finger_step", r"'0\.05'"),
    ("max_palm_step_length", {"max_palm_step": (0.02, 0.02)}, r"max_palm_step", r"0\.02"),
    ("max_palm_step_inf", {"max_palm_step": (0.02, math.inf, 0.05)}, r"max_palm_step", r"inf"),
    ("start_unknown", {"start": "lifted"}, r"start", r"'lifted'"),
    ("render_mode_unknown", {"render_mode": "video"}, r"render_mode", r"'video'"),
    ("contact_tol_inf", {"contact_tol": math.inf}, r"contact_tol", r"inf"),
    ("contact_tol_zero", {"contact_tol": 0.0}, r"contact_tol", r"0\.0"),
    ("palm_control_string", {"palm_control": "yes"}, r"palm_control", r"'yes'"),
    ("max_vertices_two", {"max_vertices": 2}, r"max_vertices", r"2"),
    ("max_vertices_float", {"max_vertices": 12.0}, r"max_vertices", r"12\.0"),
    ("randomizer_unknown_key", {"shape_randomizer": {"colour": (0, 1)}}, r"shape_randomizer",
     r"'colour'"),
    ("randomizer_reversed", {"shape_randomizer": {"size": (0.4, 0.2)}}, r"shape_randomizer",
     r"\(0\.4, 0\.2\)"),
    ("reward_weight_negative", {"reward_drop_weight": -1.0}, r"reward_drop_weight", r"-1\.0"),
    ("gamma_above_one", {"gamma": 1.5}, r"gamma", r"1\.5"),
    ("scene_empty_list", {"scene": []}, r"scene", r"\[\]"),
    ("render_width_small", {"render_width": 4}, r"render_width", r"4"),
]  # fmt: skip

OPTIONS = [
    ("options_not_dict", ["palm"], r"options", r"\['palm'\]"),
    ("options_unknown_key", {"speed": 1.0}, r"options", r"'speed'"),
    ("palm_nan", {"palm": (0.0, math.nan, 0.0)}, r"options\['palm'\]", r"nan"),
    ("palm_two_numbers", {"palm": (0.0, 0.7)}, r"options\['palm'\]", r"\(0\.0, 0\.7\)"),
    ("palm_string", {"palm": "high"}, r"options\['palm'\]", r"'high'"),
    ("palm_tilted_too_far", {"palm": (0.015, 0.9, 2.0)}, r"options\['palm'\]", r"2\.0"),
    ("palm_overlaps_object", {"palm": (0.015, 0.3, 0.0)}, r"palm", r"overlaps the object"),
    ("fingers_out_of_limits", {"fingers": (-1.5, 0.5)}, r"options\['fingers'\]", r"0\.5"),
    ("fingers_inf", {"fingers": (-1.5, -math.inf)}, r"options\['fingers'\]", r"inf"),
    ("scene_clockwise", {"scene": changed(("object", "vertices"), V[::-1])},
     r"object\.vertices", r"clockwise"),
]  # fmt: skip

ACTIONS = [
    ("action_nan", [math.nan, 0.0, 0.0, 0.0, 0.0], r"action", r"nan"),
    ("action_inf", [0.0, math.inf, 0.0, 0.0, 0.0], r"action", r"inf"),
    ("action_short", [0.1, 0.1, 0.1], r"action", r"\[0\.1, 0\.1, 0\.1\]"),
    ("action_matrix", np.zeros((5, 5)), r"action", r"\(5, 5\)"),
    ("action_string", "close", r"action", r"'close'"),
    ("action_none", None, r"action", r"None"),
    ("action_strings", ["a", "b", "c", "d", "e"], r"action", r"'a'"),
]


def ids(cases: list) -> list[str]:
    return [c[0] for c in cases]


def test_at_least_thirty_cases() -> None:
    assert len(SCENES) + len(KWARGS) + len(OPTIONS) + len(ACTIONS) >= 30
    assert len(set(ids(SCENES + KWARGS + OPTIONS + ACTIONS))) == sum(
        map(len, (SCENES, KWARGS, OPTIONS, ACTIONS))
    )
    FrictionlessGraspEnv(scene=copy.deepcopy(BASE))  # the base of the bad scenes is valid


def assert_refused(call, field: str, value: str) -> None:
    with pytest.raises((ValueError, TypeError)) as info:
        call()
    msg = message_of(info.value)
    assert re.search(field, msg), f"field {field!r} not named in {msg!r}"
    assert re.search(value, msg), f"value {value!r} not shown in {msg!r}"


ACTION = np.array([0.6, 0.6, 0.2, -0.3, 0.1], dtype=np.float32)


def twin_envs() -> tuple[FrictionlessGraspEnv, FrictionlessGraspEnv]:
    envs = tuple(FrictionlessGraspEnv("fig13", palm_control=True) for _ in range(2))
    for env in envs:
        env.reset(seed=3)
        env.step(ACTION)
    return envs


def assert_same_after(env: FrictionlessGraspEnv, twin: FrictionlessGraspEnv) -> None:
    """``env`` (which refused a call) and ``twin`` (which never saw it) step alike."""
    for _ in range(3):
        o1, r1, t1, u1, i1 = env.step(ACTION)
        o2, r2, t2, u2, i2 = twin.step(ACTION)
        assert np.all(np.isfinite(o1)) and "sim_error" not in i1
        np.testing.assert_array_equal(o1, o2)
        assert (r1, t1, u1) == (r2, t2, u2)
        np.testing.assert_array_equal(i1["object_pose"], i2["object_pose"])
        np.testing.assert_array_equal(i1["finger_angles"], i2["finger_angles"])


@pytest.mark.parametrize(("case", "scene", "field", "value"), SCENES, ids=ids(SCENES))
def test_bad_scene_refused(case: str, scene: Any, field: str, value: str) -> None:
    """Refused by the constructor, and by ``reset(options={"scene": ...})`` of a live env,
    which then keeps working as if nothing happened."""
    assert_refused(lambda: FrictionlessGraspEnv(scene=copy.deepcopy(scene)), field, value)
    env, twin = twin_envs()
    assert_refused(lambda: env.reset(options={"scene": copy.deepcopy(scene)}), field, value)
    assert_same_after(env, twin)


@pytest.mark.parametrize(("case", "kwargs", "field", "value"), KWARGS, ids=ids(KWARGS))
def test_bad_kwargs_refused(case: str, kwargs: dict, field: str, value: str) -> None:
    env, twin = twin_envs()
    assert_refused(lambda: FrictionlessGraspEnv(**{"scene": "fig13", **kwargs}), field, value)
    assert_same_after(env, twin)  # a live env is not disturbed


@pytest.mark.parametrize(("case", "options", "field", "value"), OPTIONS, ids=ids(OPTIONS))
def test_bad_reset_options_refused(case: str, options: Any, field: str, value: str) -> None:
    env, twin = twin_envs()
    assert_refused(lambda: env.reset(seed=5, options=options), field, value)
    assert_same_after(env, twin)


@pytest.mark.parametrize(("case", "action", "field", "value"), ACTIONS, ids=ids(ACTIONS))
def test_bad_action_refused(case: str, action: Any, field: str, value: str) -> None:
    env, twin = twin_envs()
    assert_refused(lambda: env.step(action), field, value)
    assert_same_after(env, twin)


def test_out_of_range_action_is_clipped_not_refused() -> None:
    """Finite actions beyond [-1, 1] act like the bound (documented), e.g. 7 like 1."""
    env, twin = twin_envs()
    o1, *_ = env.step(np.array([7.0, 1.0, -3.0, 0.0, 0.0], dtype=np.float32))
    o2, *_ = twin.step(np.array([1.0, 1.0, -1.0, 0.0, 0.0], dtype=np.float32))
    np.testing.assert_array_equal(o1, o2)
