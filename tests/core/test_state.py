"""A State or Contact built by hand refuses wrong types and non-finite values, naming the
field and the value; the simulator's own states, rebuilt through these checks, pass them."""

from __future__ import annotations

import dataclasses
from functools import cache
from typing import Any

import numpy as np
import pytest

import grasp_env
from grasp_env.core.state import Contact, Event, State


@cache
def start() -> State:
    return grasp_env.Simulator("fig13").reset()


def contact(**change: Any) -> Contact:
    """fig13's first start contact (on the support) with the fields in ``change``."""
    c = start().contacts[0]
    fields = {f.name: getattr(c, f.name) for f in dataclasses.fields(Contact)}
    return Contact(**{**fields, **change})


def state(**change: Any) -> State:
    s = start()
    return State(s.scene, s.object_pose, s.hand, **change)


@pytest.mark.parametrize(
    ("change", "error", "needle"),
    [
        ({"force": float("nan")}, ValueError, r"contact force must be finite .*, got nan"),
        ({"force": -1}, ValueError, r"contact force must be finite and in \[0, inf\), got -1"),
        ({"force": "x"}, TypeError, "contact force must be a number, got 'x'"),
        ({"gap": float("nan")}, ValueError, "contact gap must be finite .*, got nan"),
        ({"gap": np.inf}, ValueError, "contact gap must be finite .*, got inf"),
        ({"object_feature": -1}, ValueError, "contact object_feature must be .* >= 0, got -1"),
        ({"object_feature": 1.5}, TypeError, "contact object_feature must be .*, got 1.5"),
        ({"object_feature": "a"}, TypeError, "contact object_feature must be .*, got 'a'"),
        ({"hand_feature": True}, TypeError, "contact hand_feature must be .*, got True"),
    ],
    ids=[
        *("force-nan", "force-negative", "force-str", "gap-nan", "gap-inf"),
        *("feature-negative", "feature-float", "feature-str", "feature-bool"),
    ],
)
def test_a_bad_contact_field_is_named(change: dict, error: type, needle: str) -> None:
    with pytest.raises(error, match=needle):
        contact(**change)


@pytest.mark.parametrize(
    ("change", "error", "needle"),
    [
        ({"contacts": 5}, TypeError, "state contacts must be a sequence of .*Contact, got 5"),
        ({"events": [1, 2]}, TypeError, r"state events must be grasp_env\.Event, got 1"),
        ({"jammed": "yes"}, TypeError, "state jammed must be a bool, got 'yes'"),
        ({"hand_blocked": 1}, TypeError, "state hand_blocked must be a bool, got 1"),
    ],
    ids=["contacts-int", "events-ints", "jammed-str", "blocked-int"],
)
def test_a_bad_state_field_is_named(change: dict, error: type, needle: str) -> None:
    with pytest.raises(error, match=needle):
        state(**change)


def test_checked_fields_are_plain_python_values() -> None:
    """As the simulator's own contacts and states hold them: numpy scalars become ints,
    floats and bools."""
    c = contact(force=np.float32(1.5), gap=np.float64(0.0), object_feature=np.int64(1))
    assert type(c.force) is float and type(c.gap) is float and type(c.object_feature) is int
    s = state(contacts=[c], jammed=np.bool_(True), events=[Event("jam", 1.0)])
    assert s.jammed is True and isinstance(s.contacts, tuple) and isinstance(s.events, tuple)


@pytest.mark.parametrize("name", grasp_env.bundled_scenes())
def test_the_simulators_states_pass_the_checks(name: str) -> None:
    """Every state of a closing motion, its contacts rebuilt by hand, is accepted."""
    sim = grasp_env.Simulator(name)
    s = sim.reset()
    q1, q2 = s.finger_angles
    for i in range(1, 40):
        s = sim.move_hand(s, fingers=(q1 + 0.03 * i, q2 - 0.03 * i))
        rebuilt = tuple(dataclasses.replace(c) for c in s.contacts)
        copy = dataclasses.replace(s, contacts=rebuilt)
        assert [c.key for c in copy.contacts] == [c.key for c in s.contacts]
        if s.jammed:
            break
