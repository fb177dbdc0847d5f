"""Tests of the ``python -m grasp_env.analyze`` command (grasp_env.analyze.main)."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

import grasp_env
from grasp_env.analyze import main

SCENES = grasp_env.bundled_scenes()


def _field(out: str, label: str) -> str:
    m = re.search(rf"{re.escape(label)}:? ([^\n,]+)", out)
    assert m, f"{label!r} not in output:\n{out}"
    return m.group(1).strip()


@pytest.mark.parametrize("name", SCENES)
def test_every_bundled_scene(name, capsys):
    assert main(["--scene", name]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    scene = grasp_env.load_scene(name)
    assert _field(out, "scene") == scene.name
    # the printed numbers agree with values computed here from the scene's vertices
    v = scene.object.vertices_W0
    area = 0.5 * float(
        np.dot(v[:, 0], np.roll(v[:, 1], -1)) - np.dot(np.roll(v[:, 0], -1), v[:, 1])
    )
    assert float(_field(out, "area")) == pytest.approx(area, rel=1e-5)
    assert float(_field(out, "mass")) == pytest.approx(scene.object.mass, rel=1e-5)
    assert float(_field(out, "weight")) == pytest.approx(
        scene.object.mass * scene.gravity, rel=1e-5
    )
    assert float(_field(out, "width")) == pytest.approx(grasp_env.object_width(scene), rel=1e-5)
    assert re.search(r"^  left .*:$", out, re.M) and re.search(r"^  right .*:$", out, re.M)
    # initial state: contacts and closure flags as the library computes them
    state = grasp_env.Simulator(scene).reset()
    assert f"contacts ({len(state.contacts)}):" in out
    assert _field(out, "form closure") == str(grasp_env.is_form_closure(state))
    assert _field(out, "force closure") == str(grasp_env.is_force_closure(state))
    y = float(_field(out, "grip objective y*"))
    assert y == pytest.approx(grasp_env.grip_objective(state), rel=1e-9)


def _region_block(out: str, side: str) -> list[str]:
    lines = out.splitlines()
    start = next(i for i, s in enumerate(lines) if s.startswith(f"  {side} "))
    block = []
    for s in lines[start + 1 :]:
        if not s.startswith("    "):
            break
        block.append(s.strip())
    return block


def test_flat_trapezoid_regions_are_empty(capsys):
    assert main(["--scene", "flat_trapezoid"]) == 0
    out = capsys.readouterr().out
    assert _region_block(out, "left") == ["empty"]
    assert _region_block(out, "right") == ["empty"]


def test_square_regions_readable(capsys):
    """The square (vertices (-.15, 0), (.15, 0), (.15, .3), (-.15, .3)): its right side (edge
    1) is in the left region, its left side (edge 3) in the right region, whole edges; the top
    corners carry vertex subregions with normal angles in degrees."""
    assert main(["--scene", "square"]) == 0
    out = capsys.readouterr().out
    left, right = _region_block(out, "left"), _region_block(out, "right")
    assert "edge 1: t in (0, 1), from (0.15, 0) to (0.15, 0.3)" in left
    assert "edge 3: t in (0, 1), from (-0.15, 0.3) to (-0.15, 0)" in right
    assert any(
        s.startswith("vertex 2 at (0.15, 0.3): normal angle in [180.00, 225.00)") for s in left
    )
    assert any(
        s.startswith("vertex 3 at (-0.15, 0.3): normal angle in (-45.00, 0.00]") for s in right
    )


@pytest.mark.parametrize(
    ("arg", "needle"),
    [
        ("no_such_scene", "no_such_scene"),
        ("/nonexistent/dir/scene.yaml", "/nonexistent/dir/scene.yaml"),
    ],
    ids=["bad_name", "missing_path"],
)
def test_bad_scene_exits_2(arg, needle, capsys):
    assert main(["--scene", arg]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("error: ") and needle in err
    assert "Traceback" not in err


def test_invalid_scene_file_names_field(tmp_path, capsys):
    text = (grasp_env.core.scene_loading.SCENES_DIR / "square.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("width: 1.0", "width: -1.0"))
    assert main(["--scene", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "palm.width" in err and "-1.0" in err


def test_scene_path_accepted(capsys):
    path = grasp_env.core.scene_loading.SCENES_DIR / "triangle.yaml"
    assert main(["--scene", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"source: {path}" in out


def test_simulator_failure_is_reported(monkeypatch, capsys):
    def broken_reset(self):
        raise grasp_env.SimulationError("solver gave up")

    monkeypatch.setattr(grasp_env.Simulator, "reset", broken_reset)
    assert main(["--scene", "square"]) == 0
    out = capsys.readouterr().out
    assert "error: the simulator failed: SimulationError: solver gave up" in out
    assert "form closure" not in out


def test_missing_argument_exits_2(capsys):
    assert main([]) == 2
    assert "usage:" in capsys.readouterr().err


def test_module_entry_point():
    """``python -m grasp_env.analyze`` sets the exit status and prints no traceback."""
    bad = subprocess.run(
        [sys.executable, "-m", "grasp_env.analyze", "--scene", "nope"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2
    assert bad.stderr.startswith("error: ") and "Traceback" not in bad.stderr
