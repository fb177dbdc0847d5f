"""The ``small`` suite of ``benchmarks.planner_shapes``: its shapes lie in their bands, the
same for a seed every time, and its page breaks the outcomes down by vertex count and band."""

import numpy as np
import pytest

from benchmarks import planner_shapes


@pytest.mark.parametrize("k", range(len(planner_shapes.SMALL_BANDS)))
def test_small_shape_lies_in_its_band(k):
    scene = planner_shapes.small_scene(k)
    v = scene.object.vertices_W0
    width, height = v[:, 0].max() - v[:, 0].min(), v[:, 1].max() - v[:, 1].min()
    (lo, hi), profile = planner_shapes.SMALL_BANDS[k]
    assert 3 <= len(v) <= 5
    assert lo <= width < hi
    assert 0.08 <= height <= 0.55
    assert (height / width >= 0.6) == (profile == "high")
    assert np.array_equal(v, planner_shapes.small_scene(k).object.vertices_W0)


def test_small_shapes_differ_from_the_env_suites():
    small = planner_shapes.suite_scene("small", 0).object.vertices_W0
    heldout = planner_shapes.suite_scene("heldout", 0).object.vertices_W0
    assert small.shape != heldout.shape or not np.allclose(small, heldout)


def test_small_suite_page_has_a_row_per_vertex_count_and_band(tmp_path):
    page = planner_shapes.run(tmp_path / "small.md", shapes=1, suites=("small",), workers=1)
    lines = page.read_text().splitlines()
    row = next(line for line in lines if line.startswith("| small | 1 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert int(cells[2]) + int(cells[3]) == 1  # not tippable + tippable
    n = len(planner_shapes.small_scene(0).object.vertices_W0)
    assert any(line.startswith(f"| small | {n} vertices |") for line in lines)
    for band in planner_shapes.SMALL_BANDS:
        assert any(
            line.startswith(f"| small | {planner_shapes.band_name(band)} |") for line in lines
        )


def test_a_failure_reason_keeps_whether_the_object_has_a_face_turned_down():
    stuck = "fixed-palm lifting stuck from every placement: the hand wedges the object (2 of 2)"
    row = {"status": "stuck", "reason": stuck}
    assert planner_shapes._reason(row) == "fixed-palm lifting stuck from every placement"
    row["reason"] = stuck + " (no face but the supporting edge faces down: only a fingertip)"
    assert planner_shapes._reason(row) == (
        "fixed-palm lifting stuck from every placement; no face but the supporting edge faces down"
    )


def test_shapes_with_no_face_down_are_counted_by_suite():
    def plan(k, vertices, face_down, lifted, tippable=True):
        status = "form_closure" if lifted else "stuck"
        return {"suite": "small", "k": k, "vertices": vertices, "face_down": face_down,
                "tippable": tippable, "status": status, "checked": lifted}  # fmt: skip

    plans = [
        plan(0, 3, False, False),
        plan(1, 3, False, True),
        plan(2, 4, False, False),
        plan(3, 5, True, False),
        plan(4, 5, True, True),
        plan(5, 3, False, False, tippable=False),  # not tippable: left out
    ]
    assert list(planner_shapes._no_face_down(plans)) == [
        ["small", "3 (2 with 3 vertices, 1 with 4 vertices)", 1, "2 of 3"]
    ]
