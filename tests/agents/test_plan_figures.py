"""agents.plan_figures, agents.grip_branches: which steps the filmstrip shows, and the grip
adjustment's record and plot (like the paper's Fig. 14)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.grip_branches import write_branch_plot
from agents.plan_figures import frame_indices, plan_events
from grasp_env import planning
from grasp_env.simulator import Simulator


@pytest.fixture(scope="module")
def fig13():
    sim = Simulator("fig13")
    plan = planning.plan_grasp("fig13", sim=sim)
    assert plan.success
    return sim, plan


def test_grip_probes_record_what_the_adjustment_evaluated(fig13):
    _, plan = fig13
    a, b = plan.phase_bounds()["grip adjustment"]
    probes = plan.grip_probes
    # one probe per step of the adjustment (fig13 keeps four contacts: a single branch),
    # from the last lifting step to the final one
    assert [p.step for p in probes] == list(range(a - 1, b + 1))
    for p in probes:
        st = plan.steps[p.step]
        assert p.start == (st.state.hand[3], st.grip)
        assert p.kept == (0, 1, 2, 3)
        assert len(p.q1) == len(p.grip) >= 2 and all(math.isfinite(y) for y in p.grip)
        if p.chosen is not None:  # the hand moved along the branch to that q1
            nxt = plan.steps[p.step + 1]
            assert nxt.state.hand[3] == pytest.approx(p.chosen, abs=1e-9)
            assert nxt.grip < st.grip
    # at the end no evaluated neighbour lowers y*: the local minimum it reports
    last = probes[-1]
    assert last.chosen is None and "local minimum" in plan.message
    assert min(last.grip) >= plan.steps[-1].grip


def test_events_name_what_happens(fig13):
    _, plan = fig13
    events = plan_events(plan)
    lift = next(i for i, st in enumerate(plan.steps) if not st.state.on_support)
    fc = plan.form_closure_step()
    a, b = plan.phase_bounds()["grip adjustment"]
    assert events[0] == "start"
    assert events[lift].startswith("lift-off")
    assert events[fc].startswith("form closure")
    assert events[a] == "grip adjustment starts"
    assert events[b] == "final grasp"
    assert any("constrained fall" in e for e in events.values())
    assert any(e.startswith("tips") for e in events.values())


def test_frames_go_where_something_changes(fig13):
    _, plan = fig13
    idx = frame_indices(plan, 15)
    assert len(idx) == 15 and idx == sorted(set(idx))
    assert set(plan_events(plan)) <= set(idx)
    # the grip adjustment barely moves anything: it gets its first and last steps only
    a, b = plan.phase_bounds()["grip adjustment"]
    assert [i for i in idx if a <= i <= b] == [a, b]
    # fewer steps than frames: every step
    assert frame_indices(plan, 100) == list(range(len(plan.steps)))


def test_branch_plot_zooms_on_the_adjustment(fig13, tmp_path):
    pytest.importorskip("matplotlib")
    sim, plan = fig13
    out = tmp_path / "grip_branches.png"
    branches = write_branch_plot(sim, plan, out)
    assert out.stat().st_size > 10_000
    (br,) = branches
    assert br["followed"] and br["kept"] == (0, 1, 2, 3)
    q, y = np.array(br["q1"]), np.array(br["grip"])
    steps = [st.state.hand[3] for st in plan.steps[plan.grip_probes[0].step :]]
    # traced across the adjustment's range of q1, densely, with its minimum inside
    assert q.min() < min(steps) and q.max() > max(steps) and len(q) > 50
    k = int(np.argmin(y))
    assert 0 < k < len(q) - 1
    assert q[k] == pytest.approx(plan.steps[-1].state.hand[3], abs=2 * (q[1] - q[0]))
