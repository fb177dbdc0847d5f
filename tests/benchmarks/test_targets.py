"""``benchmarks.targets`` gathers the target lines of the pages, and only those; the planner
and bundled-scene pages state their targets from their own counts."""

from __future__ import annotations

from benchmarks import bundled_scenes, planner_shapes, targets

PAGE = """# A page

Machine: some CPU; grasp_env at abc1234; 2026-01-01 00:00 UTC; load average 1.0.

Some prose about a method (no target here), and a line that was met by chance.

| case | steps/s | target |
| :--- | ---: | :--- |
| a | 10 | >= 5: met |
| b | 1 | >= 5: not met |

| case | steps/s |
| :--- | ---: |
| c | 3 met |

* target: FrictionlessGrasp-v0 >= 1x LunarLander-v3: **1.2x** (met)
* moonshot: something: **0.2x** (not met)
"""


def test_page_targets_keeps_target_lines_and_rows_under_their_header():
    found = targets.page_targets(PAGE)
    assert found == [
        "",
        "| case | steps/s | target |",
        "| :--- | ---: | :--- |",
        "| a | 10 | >= 5: met |",
        "| b | 1 | >= 5: not met |",
        "* target: FrictionlessGrasp-v0 >= 1x LunarLander-v3: **1.2x** (met)",
        "* moonshot: something: **0.2x** (not met)",
    ]


def test_the_page_links_each_page_with_its_machine_line(tmp_path):
    results = tmp_path / "results"
    results.mkdir()
    (results / "one.md").write_text(PAGE)
    (results / "none.md").write_text("# No targets\n\nMachine: x\n\nJust prose.\n")
    out = targets.run(results, tmp_path / "out" / "targets.md")
    text = out.read_text()
    assert "## [one.md](../results/one.md)" in text
    assert "Machine: some CPU; grasp_env at abc1234" in text
    assert "none.md" not in text
    assert targets.run(results, results / targets.PAGE_NAME).read_text().count("## [") == 1


def _plan(suite, k, lifted, cpu, tippable=True):
    status = "form_closure" if lifted else "stuck"
    return {"suite": suite, "k": k, "tippable": tippable, "status": status,
            "checked": lifted, "cpu": cpu}  # fmt: skip


def test_planner_targets_count_the_tippable_shapes_only():
    plans = [_plan("small", k, k < 19, 0.1 * (k + 1)) for k in range(20)]
    plans.append(_plan("small", 20, False, 99.0, tippable=False))
    lines = planner_shapes._targets(plans)
    assert lines[0].endswith("**19/20 = 95%** (met)")
    assert lines[1].endswith("**1.05 s** (not met)")  # median of 0.1 .. 2.0
    assert lines[2].endswith("**2.00 s** (met)")
    plans[0] = _plan("small", 0, False, 0.1)
    assert planner_shapes._targets(plans)[0].endswith("**18/20 = 90%** (not met)")


def test_bundled_targets_leave_out_the_scenes_that_cannot_be_lifted():
    plans = [
        {"scene": "fig13", "status": "form_closure", "cpu": 0.05},
        {"scene": "flat_trapezoid", "status": "not_tippable", "cpu": 0.0},
        {"scene": "square", "status": "stuck", "cpu": 5.0},
    ]
    lines = bundled_scenes._targets(plans)
    assert lines == [
        "* target: every tippable bundled scene lifted: **1/2** (not met)",
        "* target: fig13 plan <= 0.1 s of CPU: **0.050 s** (met)",
    ]
