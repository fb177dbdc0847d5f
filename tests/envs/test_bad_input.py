"""Bad input at every boundary of the environment: scenes, env kwargs, reset options, seeds,
actions, through the class and through ``gymnasium.make`` and ``make_vec``.

Each malformed input must be refused with a ``ValueError`` or ``TypeError`` whose message names
the field and shows the value (a ``ValueError`` for reset arguments and actions). After a
refused ``reset`` or ``step`` the env must keep working exactly as if the call had not
happened: a twin env that never saw the bad call, stepped with the same actions, must give the
same observations and info; through ``gymnasium.make`` that includes its wrappers (the env
checker's first-call checks, the time limit).
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

from grasp_env.core.state import Contact
from grasp_env.envs import ENV_ID
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv

SCENES_DIR = Path(__file__).resolve().parents[2] / "grasp_env" / "scenes"
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
    ("render_mode_int", {"render_mode": 5}, r"render_mode", r"5"),
    ("render_mode_list", {"render_mode": ["rgb_array"]}, r"render_mode", r"\['rgb_array'\]"),
    ("contact_tol_inf", {"contact_tol": math.inf}, r"contact_tol", r"inf"),
    ("contact_tol_zero", {"contact_tol": 0.0}, r"contact_tol", r"0\.0"),
    ("contact_tol_below_simulator", {"contact_tol": 1e-12}, r"contact_tol", r"1e-12"),
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
    ("render_height_huge", {"render_height": 10**9}, r"render_height", r"1000000000"),
    ("max_vertices_huge", {"max_vertices": 10**15}, r"max_vertices", r"1000000000000000"),
    ("reward_weight_huge", {"reward_ctrl_weight": 1e308}, r"reward_ctrl_weight", r"1e\+308"),
    ("randomizer_size_huge", {"shape_randomizer": {"size": (0.2, 1e300)}},
     r"shape_randomizer\['size'\]", r"1e\+300"),
    ("randomizer_aspect_sliver", {"shape_randomizer": {"aspect": (1e6, 1e7)}},
     r"shape_randomizer\['aspect'\]", r"1000000\.0"),
    # shapes this large overlap the hand or put the palm above its workspace (y <= 3 w)
    ("randomizer_palm_outside", {"shape_randomizer": {"size": (5.0, 10.0)}},
     r"shape_randomizer", r"\(5\.0, 10\.0\).*no random shape"),
    # a pool entry is drawn as a 64-bit integer
    ("shape_pool_huge", {"shape_randomizer": {}, "shape_pool": 10**30}, r"shape_pool",
     r"1000000000000000000000000000000"),
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
    ("object_pose_nan", {"object_pose": (0.0, math.nan, 0.0)}, r"options\['object_pose'\]",
     r"nan"),
    ("object_pose_two_numbers", {"object_pose": (0.0, 0.2)}, r"options\['object_pose'\]",
     r"\(0\.0, 0\.2\)"),
    ("object_pose_far_up", {"object_pose": (0.015, 40.0, 0.0)}, r"options\['object_pose'\]",
     r"40\.0.*palm workspace"),
    ("object_pose_in_support", {"object_pose": (0.015, 0.05, 0.0)}, r"object_pose",
     r"object enters the support"),
    ("object_pose_in_palm", {"object_pose": (0.015, 0.7, 0.0)}, r"object_pose",
     r"overlaps the object"),
    # the scene schema's bound on angles: an angle this large has lost its precision
    ("object_pose_angle_huge", {"object_pose": (0.015, 0.2, 1e12)},
     r"options\['object_pose'\].*angle", r"1000000000000\.0"),
    ("object_pose_angle_turns", {"object_pose": (0.015, 0.2, 7.0)},
     r"options\['object_pose'\].*angle", r"7\.0"),
    ("scene_clockwise", {"scene": changed(("object", "vertices"), V[::-1])},
     r"object\.vertices", r"clockwise"),
    # Values that are not real numbers, on every key: refused, never parsed, cast or truncated.
    ("palm_complex", {"palm": (0.015, 0.9 + 1j, 0.0)}, r"options\['palm'\]", r"0\.9\+1j"),
    ("palm_complex_array", {"palm": np.array([0.015, 0.9 + 0.5j, 0.0])},
     r"options\['palm'\]", r"0\.5j"),
    ("palm_numeric_strings", {"palm": ["0.015", "0.9", "0.0"]}, r"options\['palm'\]",
     r"'0\.9'"),
    ("palm_huge_int", {"palm": (0.015, 10**400, 0.0)}, r"options\['palm'\].*finite",
     r"10000000000"),
    ("fingers_bools", {"fingers": [False, False]}, r"options\['fingers'\]", r"False"),
    ("fingers_object_array", {"fingers": np.array([-1.5, -1.5], dtype=object)},
     r"options\['fingers'\]", r"dtype=object"),
    ("fingers_none_inside", {"fingers": (-1.5, None)}, r"options\['fingers'\]", r"None"),
    ("fingers_nested", {"fingers": [[-1.5, -1.5]]}, r"options\['fingers'\]", r"\(1, 2\)"),
    ("scene_complex", {"scene": 1j}, r"options\['scene'\]", r"1j"),
    ("scene_huge_int", {"scene": 10**400}, r"options\['scene'\]", r"10000000000"),
    ("scene_unknown_name", {"scene": "0.1"}, r"options\['scene'\]", r"'0\.1'"),
    ("scene_complex_gravity", {"scene": changed(("gravity",), 1j)},
     r"options\['scene'\].*gravity", r"1j"),
    ("scene_string_density", {"scene": changed(("object", "density"), "2")},
     r"options\['scene'\].*object\.density", r"'2'"),
    ("scene_huge_vertex", {"scene": changed(("object", "vertices", 0, 0), 10**400)},
     r"options\['scene'\].*object\.vertices\[0\]\[0\]", r"10000000000"),
]  # fmt: skip

SEEDS = [
    ("seed_negative", -1, r"seed", r"-1"),
    ("seed_float", 1.5, r"seed", r"1\.5"),
    ("seed_string", "3", r"seed", r"'3'"),
    ("seed_complex", 3j, r"seed", r"3j"),
    ("seed_bool", True, r"seed", r"True"),
    ("seed_numpy_negative", np.int64(-1), r"seed", r"-1"),
    ("seed_numpy_bool", np.bool_(True), r"seed", r"True"),
]

ACTIONS = [
    ("action_nan", [math.nan, 0.0, 0.0, 0.0, 0.0], r"action", r"nan"),
    ("action_inf", [0.0, math.inf, 0.0, 0.0, 0.0], r"action", r"inf"),
    ("action_short", [0.1, 0.1, 0.1], r"action", r"\[0\.1, 0\.1, 0\.1\]"),
    ("action_matrix", np.zeros((5, 5)), r"action", r"\(5, 5\)"),
    ("action_string", "close", r"action", r"'close'"),
    ("action_none", None, r"action", r"None"),
    ("action_strings", ["a", "b", "c", "d", "e"], r"action", r"'a'"),
    ("action_complex_array", np.array([1 + 1j, 0, 0, 0, 0]), r"action", r"1\.\+1\.j"),
    ("action_complex_python", [0.5, 1j, 0.0, 0.0, 0.0], r"action", r"1j"),
    ("action_complex_scalar", 1 + 1j, r"action", r"\(1\+1j\)"),
    ("action_numeric_string", "0.1", r"action", r"'0\.1'"),
    ("action_numeric_strings", ["0.1"] * 5, r"action", r"'0\.1'"),
    ("action_huge_int", [10**400, 0, 0, 0, 0], r"action.*finite", r"\[10000000000"),
    ("action_object_array", np.array([0.1] * 5, dtype=object), r"action", r"dtype=object"),
    ("action_bool_array", np.ones(5, dtype=bool), r"action", r"True"),
    ("action_bools", [True, False, True, False, True], r"action", r"True"),
    ("action_none_inside", [0.1, None, 0.1, 0.1, 0.1], r"action", r"None"),
    ("action_nested", [[0.1] * 5], r"action", r"\(1, 5\)"),
    ("action_ragged", [[0.1, 0.1], [0.1]], r"action", r"\[\[0\.1, 0\.1\], \[0\.1\]\]"),
    ("action_nan_float32", np.array([0, 0, np.nan, 0, 0], np.float32), r"action", r"nan"),
    ("action_nan_last", np.array([0.5, 0, 0, 0, np.nan]), r"action", r"nan"),
    ("action_infs_cancelling", np.array([np.inf, -np.inf, 0, 0, 0]), r"action", r"inf"),
    ("action_masked", np.ma.masked_array([0.1] * 5, [0, 1, 0, 0, 0]), r"action", r"masked"),
]


def ids(cases: list) -> list[str]:
    return [c[0] for c in cases]


def test_at_least_thirty_cases() -> None:
    cases = (SCENES, KWARGS, OPTIONS, SEEDS, ACTIONS)
    assert sum(map(len, cases)) >= 30
    assert len({c[0] for group in cases for c in group}) == sum(map(len, cases))
    FrictionlessGraspEnv(scene=copy.deepcopy(BASE))  # the base of the bad scenes is valid


def assert_refused(call, field: str, value: str, error: Any = (ValueError, TypeError)) -> None:
    with pytest.raises(error) as info:
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
    error = ValueError if isinstance(options, dict) else TypeError
    assert_refused(lambda: env.reset(seed=5, options=options), field, value, error)
    assert_same_after(env, twin)


@pytest.mark.parametrize(("case", "seed", "field", "value"), SEEDS, ids=ids(SEEDS))
def test_bad_seed_refused(case: str, seed: Any, field: str, value: str) -> None:
    env, twin = twin_envs()
    assert_refused(lambda: env.reset(seed=seed), field, value, ValueError)
    assert_same_after(env, twin)


def test_numpy_integer_seeds_are_ints() -> None:
    """A numpy integer seeds as the same Python int does (numbers are numbers, whatever
    their type), in the single env and in the batched one, alone or in a list."""
    env, twin = twin_envs()
    np.testing.assert_array_equal(env.reset(seed=np.int64(3))[0], twin.reset(seed=3)[0])
    venv, vtwin = (gym.make_vec("FrictionlessGrasp-v0", num_envs=2) for _ in range(2))
    want = vtwin.reset(seed=5)[0]
    np.testing.assert_array_equal(venv.reset(seed=np.int64(5))[0], want)
    np.testing.assert_array_equal(venv.reset(seed=[np.int64(5), np.uint8(6)])[0], want)
    np.testing.assert_array_equal(venv.reset(seed=np.array([5, 6]))[0], want)


@pytest.mark.parametrize(("case", "action", "field", "value"), ACTIONS, ids=ids(ACTIONS))
def test_bad_action_refused(case: str, action: Any, field: str, value: str) -> None:
    env, twin = twin_envs()
    before = env._observation()
    assert_refused(lambda: env.step(action), field, value, ValueError)
    np.testing.assert_array_equal(env._observation(), before)
    assert_same_after(env, twin)


@pytest.mark.parametrize(
    "call",
    [
        lambda env: env.step([10**400, 0, 0, 0, 0]),
        lambda env: env.step(np.zeros((40, 5))),
        lambda env: env.reset(options={"palm": ["0.1" * 50] * 3}),
        lambda env: env.reset(options={"scene": 10**400}),
    ],
    ids=["action-huge-int", "action-matrix", "palm-long-strings", "scene-huge-int"],
)
def test_long_values_are_shortened(call) -> None:
    env = FrictionlessGraspEnv("fig13", palm_control=True)
    env.reset(seed=0)
    with pytest.raises(ValueError) as info:
        call(env)
    msg = str(info.value)
    assert "..." in msg and "\n" not in msg and len(msg) < 200, msg


def test_refused_reset_keeps_the_random_generator() -> None:
    """A reset refused after the scene is known (the hand overlaps the object) neither
    reseeds nor advances the generator: the next unseeded reset is the twin's."""
    envs = [FrictionlessGraspEnv("fig13", start="random") for _ in range(2)]
    for env in envs:
        env.reset(seed=1)
    env, twin = envs
    assert_refused(
        lambda: env.reset(seed=7, options={"palm": (0.015, 0.3, 0.0)}), r"palm", r"overlaps"
    )
    assert env.np_random_seed == twin.np_random_seed == 1
    (o1, i1), (o2, i2) = env.reset(), twin.reset()
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(i1["palm_pose"], i2["palm_pose"])


def test_refused_unseeded_reset_takes_back_its_draws() -> None:
    """An unseeded reset refused after it drew from the env's generator (which of two scenes)
    puts the generator back: the next resets are the twin's, scene for scene."""
    envs = [FrictionlessGraspEnv(["fig13", "square"], start="random") for _ in range(2)]
    for env in envs:
        env.reset(seed=4)
    env, twin = envs
    drawn = env.np_random.bit_generator.state
    assert_refused(lambda: env.reset(options={"palm": (0.015, 0.3, 0.0)}), r"palm", r"refused")
    assert env.np_random.bit_generator.state == drawn
    for _ in range(4):
        (o1, i1), (o2, i2) = env.reset(), twin.reset()
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(i1["palm_pose"], i2["palm_pose"])
        assert env.scene.name == twin.scene.name


@pytest.mark.parametrize(
    "convert",
    [lambda a: a.astype(np.longdouble), lambda a: np.ma.masked_array(a), lambda a: a.tolist()],
    ids=["longdouble", "masked_nothing_masked", "list"],
)
def test_other_real_action_types_act_as_float64(convert) -> None:
    env, twin = twin_envs()
    rng = np.random.default_rng(3)
    for _ in range(5):
        a = rng.uniform(-1, 1, env.action_space.shape)
        got, want = env.step(convert(a)), twin.step(a)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1] == want[1]


def test_a_state_of_another_scene_is_refused() -> None:
    env, twin = twin_envs()
    other = FrictionlessGraspEnv(scene="square")
    other.reset(seed=0)
    with pytest.raises(ValueError, match="state is of scene 'square', not of 'fig13'"):
        env.simulate_action(other.state, np.zeros(env.action_space.shape))
    assert_same_after(env, twin)


def test_a_state_with_a_mislabelled_contact_is_refused() -> None:
    """A hand-built state whose support contact is relabelled as a finger's: the env's
    compiled move would take it as a known contact and stop the hand with a false jam."""
    env, twin = twin_envs()
    state = env.state
    i, c = next((i, c) for i, c in enumerate(state.contacts) if c.body == "support")
    bad = Contact("finger1", c.kind, c.point, c.normal, c.force, c.object_feature, c.hand_feature)
    contacts = (*state.contacts[:i], bad, *state.contacts[i + 1 :])
    with pytest.raises(ValueError, match=r"^state.contacts .* are not the contacts at the state"):
        env.simulate_action(replace(state, contacts=contacts), ACTION)
    assert_same_after(env, twin)


def test_out_of_range_action_is_clipped_not_refused() -> None:
    """Finite actions beyond [-1, 1] act like the bound (documented), e.g. 7 like 1."""
    env, twin = twin_envs()
    o1, *_ = env.step(np.array([7.0, 1.0, -3.0, 0.0, 0.0], dtype=np.float32))
    o2, *_ = twin.step(np.array([1.0, 1.0, -1.0, 0.0, 0.0], dtype=np.float32))
    np.testing.assert_array_equal(o1, o2)
    # finite, but their sum overflows
    o1, *_ = env.step(np.array([1e308, 1e308, -1e308, -1e308, 0.0]))
    o2, *_ = twin.step(np.array([1.0, 1.0, -1.0, -1.0, 0.0]))
    np.testing.assert_array_equal(o1, o2)


# ---------------------------------------------------------------------------------------
# Through gymnasium.make (the env itself, with its own time limit): the same refusals
# ---------------------------------------------------------------------------------------

KW = {"scene": "fig13", "palm_control": True}
MAKERS = {
    "make": lambda: gym.make(ENV_ID, **KW),
    "time-limit": lambda: gym.make(ENV_ID, time_limit=50, **KW),
    "no-time-limit": lambda: gym.make(ENV_ID, time_limit=None, **KW),
}
MAKE_IDS = list(MAKERS)

#: Refused resets: (id, reset kwargs, field regex, value regex).
RESETS = [
    ("palm_two_numbers", {"seed": 0, "options": {"palm": [0, 0.7]}}, r"options\['palm'\]",
     r"\[0, 0\.7\]"),
    ("palm_overlaps_object", {"seed": 0, "options": {"palm": (0.015, 0.3, 0.0)}}, r"palm",
     r"overlaps the object"),
    ("palm_complex", {"options": {"palm": np.array([0.015, 0.9 + 1j, 0.0])}},
     r"options\['palm'\]", r"1\.j"),
    ("fingers_strings", {"options": {"fingers": ["-1.5", "-1.5"]}}, r"options\['fingers'\]",
     r"'-1\.5'"),
    ("scene_complex", {"options": {"scene": 1j}}, r"options\['scene'\]", r"1j"),
    ("seed_negative", {"seed": -1}, r"seed", r"-1"),
]  # fmt: skip


@pytest.mark.parametrize("mode", [5, ["rgb_array"], b"rgb_array", None.__class__])
def test_made_env_refuses_a_render_mode_that_is_not_a_string(mode) -> None:
    """gymnasium.make reads the mode before the env does: still an error naming it."""
    with pytest.raises(ValueError, match=r"^render_mode must be None or one of"):
        gym.make(ENV_ID, render_mode=mode, **KW)
    with pytest.raises(ValueError, match=r"render_mode"):
        gym.make_vec(ENV_ID, num_envs=2, render_mode=mode)
    env = gym.make(ENV_ID, render_mode="rgb_array", **KW)  # the modes it has still work
    env.reset(seed=0)
    assert env.render().ndim == 3


def made_twins(make) -> tuple[gym.Env, gym.Env]:
    envs = make(), make()
    for env in envs:
        env.reset(seed=3)
    return envs


@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKE_IDS)
@pytest.mark.parametrize(("case", "kwargs", "field", "value"), RESETS, ids=ids(RESETS))
def test_made_env_refused_first_reset(make, case: str, kwargs: dict, field: str, value: str):
    """A refused first reset leaves the made env as new: reset and step then work and match
    a twin's."""
    env, twin = make(), make()
    assert_refused(lambda: env.reset(**kwargs), field, value, ValueError)
    (o1, _), (o2, _) = env.reset(seed=0), twin.reset(seed=0)
    np.testing.assert_array_equal(o1, o2)
    env.action_space.seed(0)
    action = env.action_space.sample()
    np.testing.assert_array_equal(env.step(action)[0], twin.step(action)[0])
    assert_same_after(env, twin)


@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKE_IDS)
@pytest.mark.parametrize(("case", "kwargs", "field", "value"), RESETS, ids=ids(RESETS))
def test_made_env_refused_reset_mid_episode(make, case: str, kwargs: dict, field: str, value):
    env, twin = made_twins(make)
    for e in (env, twin):
        e.step(ACTION)
    before = env.unwrapped._observation()
    assert_refused(lambda: env.reset(**kwargs), field, value, ValueError)
    np.testing.assert_array_equal(env.unwrapped._observation(), before)
    assert_same_after(env, twin)


def test_made_env_refused_reset_keeps_the_time_limit() -> None:
    """After a refused reset the episode is still truncated at its limit (gymnasium's
    ``TimeLimit`` would have zeroed its count before passing the reset on)."""
    env, twin = made_twins(lambda: gym.make(ENV_ID, time_limit=3, **KW))
    for e in (env, twin):
        e.step(ACTION)
    assert_refused(lambda: env.reset(options={"palm": [0, 0.7]}), r"palm", r"0\.7", ValueError)
    truncated = [(env.step(ACTION)[3], twin.step(ACTION)[3]) for _ in range(2)]
    assert truncated == [(False, False), (True, True)]


@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKE_IDS)
@pytest.mark.parametrize(("case", "action", "field", "value"), ACTIONS, ids=ids(ACTIONS))
def test_made_env_bad_action_refused(make, case: str, action: Any, field: str, value: str):
    """Refused as the first step (the env checker's first-step check comes after it)."""
    env, twin = made_twins(make)
    before = env.unwrapped._observation()
    assert_refused(lambda: env.step(action), field, value, ValueError)
    np.testing.assert_array_equal(env.unwrapped._observation(), before)
    assert_same_after(env, twin)


@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKE_IDS)
def test_made_env_bad_action_refused_mid_episode(make) -> None:
    """Refused after steps: the time limit's count and the env are as a twin's that never
    saw the bad action."""
    env, twin = made_twins(make)
    for _ in range(4):
        env.step(ACTION)
        twin.step(ACTION)
    assert_refused(lambda: env.step([math.nan] * 5), r"action", r"nan", ValueError)
    assert_same_after(env, twin)


def test_make_vec_sync_refusals() -> None:
    """Through ``make_vec`` (sync): a refused reset or batch of actions (each sub-env's action
    bad, so that the first sub-env refuses it) leaves the vector env usable and unchanged."""
    venvs = [gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync", **KW) for _ in range(2)]
    venv, twin = venvs
    try:
        assert_refused(
            lambda: venv.reset(seed=0, options={"palm": [0, 0.7]}), r"palm", r"0\.7", ValueError
        )
        (o1, _), (o2, _) = venv.reset(seed=3), twin.reset(seed=3)
        np.testing.assert_array_equal(o1, o2)
        batch = np.stack([ACTION, ACTION])
        bad_batches = [
            batch + 1j,
            np.where(np.eye(2, 5, dtype=bool), np.nan, batch),
            batch.astype(object),
            batch.astype(str),
            batch.astype(bool),
        ]
        for bad in bad_batches:
            assert_refused(lambda bad=bad: venv.step(bad), r"action", r"array", ValueError)
            np.testing.assert_array_equal(venv.step(batch)[0], twin.step(batch)[0])
        assert_refused(lambda: venv.reset(options={"fingers": 1j}), r"fingers", r"1j", ValueError)
        for _ in range(2):
            np.testing.assert_array_equal(venv.step(batch)[0], twin.step(batch)[0])
    finally:
        for v in venvs:
            v.close()
