"""``benchmarks.bundled_scenes``: its fig13 facts read the plan's states as the geometry does,
the scripted policy through the env meets the plan, and the page's parts are written."""

from __future__ import annotations

import pytest

import grasp_env
from benchmarks import bundled_scenes
from grasp_env.core import geometry as geo
from grasp_env.core.scene import DEFAULT_CONTACT_TOL


@pytest.fixture(scope="module")
def fig13_row() -> dict:
    return bundled_scenes.plan_row("fig13", 300.0, timeline=True)


def test_liftoff_is_the_first_state_whose_object_clears_the_support(fig13_row):
    """The timeline's support flag against the object's lowest vertex, recomputed from the
    plan's poses: the object is off the support where its lowest vertex is above the
    contact tolerance."""
    from grasp_env import planning

    scene = grasp_env.load_scene("fig13")
    plan = planning.plan_grasp(scene)
    lowest = [
        geo.transform(st.state.object_pose, scene.object.vertices_B)[:, 1].min()
        for st in plan.steps
    ]
    tol = DEFAULT_CONTACT_TOL * scene.palm.width
    expected = [bool(y <= tol) for y in lowest]
    assert [s["on_support"] for s in fig13_row["steps"]] == expected
    assert fig13_row["steps"][0]["on_support"] and not fig13_row["steps"][-1]["on_support"]


def test_fig13_page_part_names_every_paper_fact(fig13_row):
    lines = bundled_scenes._fig13(fig13_row)
    text = "\n".join(lines)
    for fact in bundled_scenes.PAPER_FIG13:
        assert f"| {fact} |" in text
    assert f"step {fig13_row['form_closure']}" in text
    # one timeline row a plan step
    assert sum(line.startswith("| ") and line[2].isdigit() for line in lines) == len(
        fig13_row["steps"]
    )


def test_the_policy_from_the_plans_placement_closes_where_the_plan_does(fig13_row):
    """From ``"preliftoff"`` (the plan's placement, fingers closed) each lifting increment
    of 0.02 rad is one env action, so the env's first success is the plan's form-closure
    step: two ways to the same grasp."""
    ep = bundled_scenes.episode_row("fig13", "preliftoff", False, 300.0)
    assert ep["first"] == fig13_row["form_closure"]
    assert ep["end"] == "success" and not ep["fallback"]


def test_a_scene_without_a_tippability_region_is_reported_so():
    row = bundled_scenes.plan_row("flat_trapezoid", 60.0, timeline=False)
    assert row["status"] == "not_tippable"
    lines = bundled_scenes._plans_table([row])
    assert any(line.startswith("- flat_trapezoid (not_tippable): ") for line in lines)


def test_episodes_table_has_a_row_an_episode():
    eps = [
        {"scene": "fig13", "start": "scene", "palm_control": False, "first": 27, "steps": 200,
         "end": "success", "fallback": False, "cpu": 1.0},
        {"scene": "square", "start": "scene", "palm_control": True, "first": None,
         "steps": 200, "end": "no grasp", "fallback": False, "cpu": 9.0},
    ]  # fmt: skip
    lines = bundled_scenes._episodes_table(eps)
    assert len(lines) == 4
    assert "| fig13 | scene | no | 27 | 200 | success | lifts from the env's hand |" in lines[2]
    assert "| square | scene | yes | - | 200 | no grasp | - |" in lines[3]


def test_command_refuses_bad_arguments():
    for argv in (["--workers", "0"], ["--timeout", "-1"], ["--timeline", "fig14"]):
        with pytest.raises(SystemExit) as exc:
            bundled_scenes.main(argv)
        assert exc.value.code == 2
