"""Smoke test of the benchmark suite: every piece runs on a tiny budget and writes its page.

No timing assertions: the numbers of a tiny run on a shared machine mean nothing.
"""

import json

import pytest

from benchmarks import memory, planner_shapes, profile_step, throughput, work_precision


@pytest.mark.parametrize(
    "piece",
    [
        pytest.param(lambda out: throughput.run(True, out, budget=0.05, rounds=1), id="throughput"),
        pytest.param(
            lambda out: work_precision.run(True, out, paths=1, moves=2, fig13=False),
            id="work_precision",
        ),
        pytest.param(lambda out: profile_step.run(True, out, steps=3, closing=False), id="profile"),
        pytest.param(lambda out: memory.run(True, out, steps=2, repeat=1, workers=2), id="memory"),
    ],
)
def test_piece_writes_markdown(piece, tmp_path):
    out = tmp_path / "page.md"
    assert piece(out) == out
    text = out.read_text()
    assert text.startswith("# ") and "Machine:" in text and "| ---" in text


def test_profile_baseline_columns(tmp_path):
    first = profile_step.run(True, tmp_path / "a.md", steps=2, closing=False)
    second = profile_step.run(
        True, tmp_path / "b.md", steps=2, baseline=first.with_suffix(".json"), closing=False
    )
    assert "after / before" in second.read_text()
    record = json.loads(first.with_suffix(".json").read_text())
    assert set(profile_step.CONFIGS) <= set(record)


def test_planner_shapes_page_holds_each_plan(tmp_path):
    page = planner_shapes.run(tmp_path / "shapes.md", seed=3, shapes=1, timeout=120)
    text = page.read_text()
    assert text.startswith("# ") and "Machine:" in text
    row = next(line for line in text.splitlines() if line.startswith("| 3 |"))
    assert "crash" not in row and "timeout" not in row  # the worker process ran the plan
