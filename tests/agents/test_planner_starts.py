"""Starts along the planner's lifts (agents.planner_starts) and the reverse curriculum that
draws them (agents.wrappers.PlannerStarts)."""

from __future__ import annotations

import pickle
import re

import gymnasium as gym
import numpy as np
import pytest

from agents.planner_starts import (
    APPROACH_SPACING,
    ENV_ID,
    collect,
    main,
    palm_travel,
    scripted_episode,
    select,
    trajectory,
)
from agents.wrappers import PlannerStarts
from grasp_env.errors import SimulationError


@pytest.fixture(scope="module")
def starts(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("starts") / "starts.pkl"
    assert main(["--out", str(path), "--shapes", "3", "--seed", "0"]) == 0
    return str(path)


def test_lift_states_restart_where_the_planner_left_them(starts):
    with open(starts, "rb") as f:
        lifts = pickle.load(f)
    assert lifts and all(len(t["hands"]) == len(t["poses"]) > 0 for t in lifts)
    env = gym.make(ENV_ID).unwrapped
    for lift in lifts:
        # The lift's last state is held off the support in form closure: a reset there
        # stays there, a grasp from the first step.
        hand, pose = lift["hands"][-1], lift["poses"][-1]
        options = {"scene": lift["scene"], "palm": hand[:3], "fingers": hand[3:],
                   "object_pose": pose}  # fmt: skip
        _, info = env.reset(seed=0, options=options)
        assert info["is_success"]
        assert np.allclose(env.state.object_pose, pose, atol=1e-9)
        assert np.array_equal(env.state.hand, hand)


def test_approach_states_lead_from_the_scene_start_to_the_lift():
    env = gym.make(ENV_ID).unwrapped
    env.reset(seed=1)
    scene = env.scene
    lift, whole = trajectory(scene, 1), trajectory(scene, 1, approach=True)
    k = len(whole["hands"]) - len(lift["hands"])
    # the lift's states end the whole trajectory unchanged; before them the placement
    assert k > 1
    assert np.array_equal(whole["hands"][k:], lift["hands"])
    assert np.array_equal(whole["poses"][k:], lift["poses"])
    rest = env.simulator.reset()
    assert np.array_equal(whole["hands"][0], scene.initial_hand)
    # consecutive hands at most one action apart (palm widths, rad), up to rounding
    steps = np.abs(np.diff(whole["hands"][:k], axis=0))
    w = scene.palm.width
    assert steps[:, :2].max() <= APPROACH_SPACING[0] * w * (1 + 1e-12)
    assert steps[:, 2].max() <= APPROACH_SPACING[1] * (1 + 1e-12)
    assert steps[:, 3:].max() <= APPROACH_SPACING[2] * (1 + 1e-12)
    # along the approach the hand is clear and the object rests where the scene leaves it:
    # a reset there keeps both, with no contact but the support's
    for i in range(0, k - 1, 7):
        hand = whole["hands"][i]
        assert np.array_equal(whole["poses"][i], rest.object_pose)
        options = {"scene": scene, "palm": hand[:3], "fingers": hand[3:],
                   "object_pose": whole["poses"][i]}  # fmt: skip
        _, info = env.reset(seed=0, options=options)
        assert {c.body for c in env.state.contacts} == {"support"}
        assert np.array_equal(env.state.object_pose, rest.object_pose)
        assert not info["is_success"]
    # the placement: the plan's pre-liftoff state, the hand touching the object at rest
    assert np.allclose(whole["poses"][k - 1], rest.object_pose, atol=1e-9)


@pytest.mark.parametrize("seed", [0, 5])
def test_scripted_states_follow_the_lifting_tasks_episode_to_its_grasp(seed):
    """The scripted planner's episode from the lifting task's own start: every state one env
    step from the one before, the first the task's start, the last the first grasp. Shape 5's
    first placement does not lift: the policy moves the palm to another one."""
    found = scripted_episode(seed)
    env = gym.make(ENV_ID, palm_control=True).unwrapped
    env.reset(seed=seed)
    assert np.array_equal(found["hands"][0], env.state.hand)
    assert np.array_equal(found["poses"][0], env.state.object_pose)
    w = env.scene.palm.width
    steps = np.abs(np.diff(found["hands"], axis=0))
    largest = np.concatenate([env.max_palm_step * [w, w, 1.0], [env.max_finger_step] * 2])
    assert (steps <= largest * (1 + 1e-6)).all()
    palm_moved = np.abs(found["hands"][:, :3] - found["hands"][0, :3]).max()
    assert (palm_moved > 0.05 * w) == (seed == 5)
    successes = []
    for hand, pose in zip(found["hands"], found["poses"], strict=True):
        options = {"scene": env.scene, "palm": hand[:3], "fingers": hand[3:], "object_pose": pose}
        successes.append(env.reset(seed=0, options=options)[1]["is_success"])
    assert successes[-1] and not any(successes[:-1])


def test_a_scripted_episode_that_does_not_grasp_gives_no_states(monkeypatch):
    def still(self, obs):
        return np.zeros(5, np.float32)

    monkeypatch.setattr("agents.planner_starts.ScriptedPolicy.act", still)
    assert scripted_episode(0) is None


def test_curriculum_reaches_back_from_form_closure(starts):
    env = PlannerStarts(gym.make(ENV_ID), starts, probability=1.0, curriculum_steps=100,
                        first_reach=0.25)  # fmt: skip
    env.reset(seed=3)
    for lift in env.lifts:
        lift["index"] = {tuple(p): i for i, p in enumerate(lift["poses"])}
    for _ in range(60):  # the last quarter of each lift (rounded up), its end included
        options = env.start_options()
        lift = next(t for t in env.lifts if t["scene"] is options["scene"])
        n = len(lift["poses"])
        assert lift["index"][tuple(options["object_pose"])] >= n - -(-n // 4)
    assert env.reach == 0.25
    env.steps = 50
    assert env.reach == pytest.approx(0.625)
    env.steps = 1000
    assert env.reach == 1.0
    earliest = []
    for _ in range(200):
        options = env.start_options()
        lift = next(t for t in env.lifts if t["scene"] is options["scene"])
        earliest.append(lift["index"][tuple(options["object_pose"])])
    assert min(earliest) == 0  # the placement the lift starts from is drawn too


def test_draws_follow_the_seed_and_the_probability(starts):
    def first_options(seed, probability):
        env = PlannerStarts(gym.make(ENV_ID), starts, probability=probability)
        env.reset(seed=seed)
        return [env.start_options() for _ in range(20)]

    a, b = first_options(7, 0.5), first_options(7, 0.5)
    assert [o is None for o in a] == [o is None for o in b]
    assert 0 < sum(o is None for o in a) < 20
    assert all(o is None for o in first_options(7, 0.0))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"probability": 1.5}, r"probability .* 1\.5"), ({"first_reach": 0.0}, r"first_reach .* 0\.0"),
     ({"curriculum_steps": 0}, r"curriculum_steps .* 0")],
)  # fmt: skip
def test_bad_wrapper_arguments_are_named(starts, kwargs, match):
    with pytest.raises(ValueError, match=match):
        PlannerStarts(gym.make(ENV_ID), starts, **kwargs)


def test_reserved_seeds_are_refused():
    with pytest.raises(ValueError, match=r"999998.*held-out"):
        collect(5, 999_998)


def test_a_start_the_simulator_cannot_settle_is_the_envs_own(starts, monkeypatch):
    env = PlannerStarts(gym.make(ENV_ID), starts, probability=1.0)
    inner = env.unwrapped
    reset = inner.reset

    def failing(*, seed=None, options=None):
        if options is not None:
            raise SimulationError("no rest found")
        return reset(seed=seed, options=options)

    monkeypatch.setattr(inner, "reset", failing)
    _, info = env.reset(seed=0)
    assert env.unsettled == 1 and not info["is_success"]  # the lifting task's own start


def test_a_missing_starts_file_is_named_with_the_command_that_writes_it(tmp_path):
    missing = str(tmp_path / "starts.pkl")
    with pytest.raises(ValueError, match=r"starts .*starts\.pkl.* agents\.planner_starts"):
        PlannerStarts(gym.make(ENV_ID), missing)


@pytest.mark.parametrize(
    "content", [b"not a pickle", pickle.dumps({"seed": 1}), pickle.dumps([{"seed": 1}])]
)
def test_a_file_that_holds_no_lifts_is_named_by_both_readers(tmp_path, content):
    path = tmp_path / "bad.pkl"
    path.write_bytes(content)
    with pytest.raises(ValueError, match=r"^starts .*bad\.pkl.* is not a starts file"):
        PlannerStarts(gym.make(ENV_ID), str(path))
    with pytest.raises(ValueError, match=r"^--select .*bad\.pkl.* is not a starts file"):
        select(path, 0.01)


def test_approach_and_scripted_states_exclude_each_other():
    with pytest.raises(ValueError, match=r"--approach and --scripted"):
        collect(1, 0, approach=True, scripted=True)


def test_a_list_of_starts_files_pools_their_lifts(starts, tmp_path):
    one = PlannerStarts(gym.make(ENV_ID), starts)
    both = PlannerStarts(gym.make(ENV_ID), [starts, starts])
    assert len(both.lifts) == 2 * len(one.lifts)
    for bad in (5, [starts, 5], []):
        with pytest.raises(ValueError, match=r"starts .*(file name|names no file)"):
            PlannerStarts(gym.make(ENV_ID), bad)
    missing = str(tmp_path / "other.pkl")
    with pytest.raises(ValueError, match=r"starts .*other\.pkl.* agents\.planner_starts"):
        PlannerStarts(gym.make(ENV_ID), [starts, missing])


def _file_of(env, options) -> int:
    """Which of the wrapper's files the drawn start's lift came from."""
    index = next(i for i, t in enumerate(env.lifts) if t["scene"] is options["scene"])
    return next(k for k, (first, count) in enumerate(env._files) if first <= index < first + count)


def test_weights_set_each_files_share_of_the_starts(starts, tmp_path):
    one = tmp_path / "one.pkl"
    with open(starts, "rb") as f:
        one.write_bytes(pickle.dumps(pickle.load(f)[:1]))  # one lift against the fixture's
    env = PlannerStarts(gym.make(ENV_ID), [starts, str(one)], probability=1.0, weights=[1, 3])
    assert len(env.lifts) > 2
    env.reset(seed=11)
    draws = [_file_of(env, env.start_options()) for _ in range(2000)]
    # pooled, the single lift would start 1 / len(lifts) of them; weighed, 3 / 4 (binomial
    # standard deviation about 0.01)
    assert abs(np.mean(draws) - 0.75) < 0.04
    only = PlannerStarts(gym.make(ENV_ID), [starts, str(one)], probability=1.0, weights=[0, 2])
    only.reset(seed=11)
    assert all(_file_of(only, only.start_options()) == 1 for _ in range(50))


@pytest.mark.parametrize(
    "weights", [[1.0], [1, 2, 3], [-1, 2], [0, 0], ["a", 1], [True, 1], [float("nan"), 1], "ab", 3]
)
def test_bad_weights_are_named(starts, weights):
    with pytest.raises(ValueError, match=r"weights must be 2 non-negative .*got"):
        PlannerStarts(gym.make(ENV_ID), [starts, starts], weights=weights)


def test_select_keeps_the_lifts_whose_palm_leaves_its_start(starts, tmp_path):
    with open(starts, "rb") as f:
        lifts = pickle.load(f)
    moved = []
    for k, lift in enumerate(lifts):  # palm moved by k * 0.01 palm widths at one state
        lift = dict(lift, hands=lift["hands"].copy())
        lift["hands"][:] = lift["hands"][0]
        w = lift["scene"].palm.width
        lift["hands"][-1, :2] += np.array([0.6, -0.8]) * (0.01 * k * w)
        moved.append(lift)
    for k, lift in enumerate(moved):
        assert palm_travel(lift) == pytest.approx(0.01 * k, abs=1e-12)
    path = tmp_path / "moved.pkl"
    path.write_bytes(pickle.dumps(moved))
    assert [t["seed"] for t in select(path, 0.005)] == [t["seed"] for t in moved[1:]]
    out = tmp_path / "kept.pkl"
    assert main(["--out", str(out), "--select", str(path), "--palm-travel", "0.015"]) == 0
    with open(out, "rb") as f:
        assert [t["seed"] for t in pickle.load(f)] == [t["seed"] for t in moved[2:]]


@pytest.mark.parametrize(
    ("args", "match"),
    [(["--palm-travel", "0.01"], "go together"), (["--select", "x.pkl"], "go together"),
     (["--select", "S", "--palm-travel", "0.01", "--scripted"], "excludes --approach"),
     (["--select", "S", "--palm-travel", "-1"], r"--palm-travel .* -1"),
     (["--select", "S", "--palm-travel", "nan"], r"--palm-travel .* nan"),
     (["--select", "missing.pkl", "--palm-travel", "0.01"], r"--select .*missing\.pkl")],
)  # fmt: skip
def test_bad_selections_are_named(starts, tmp_path, capsys, args, match):
    args = [starts if a == "S" else str(tmp_path / a) if a.endswith(".pkl") else a for a in args]
    with pytest.raises(SystemExit) as exc:
        main(["--out", str(tmp_path / "out.pkl"), *args])
    assert exc.value.code == 2
    assert re.search(match, capsys.readouterr().err)
    assert not (tmp_path / "out.pkl").exists()
