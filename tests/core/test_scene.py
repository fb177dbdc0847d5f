"""Tests of :mod:`grasp_env.core.scene`: the bundled scenes, the paper's section-4 set-up, mass
properties against independent computations, and refusal of malformed scenes.

Every geometric quantity is recomputed here without :mod:`grasp_env.core.geometry`: areas and
centroids by a triangle fan from vertex 0, the object width by projecting on many
directions, inertias by numerical integration (row slicing and a 2-D midpoint grid) and by
closed forms for rectangles and triangles.
"""

from __future__ import annotations

import copy
import importlib.resources
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from grasp_env.core import scene as scene_mod
from grasp_env.core.scene import Scene
from grasp_env.core.scene_loading import bundled_scenes, load_scene, scene_from_dict
from grasp_env.errors import SceneError

SCENES_DIR = Path(__file__).resolve().parents[2] / "grasp_env" / "scenes"
SCENE_FILES = sorted(p.stem for p in SCENES_DIR.glob("*.yaml"))
REQUIRED_SCENES = (
    "fig13",
    "square",
    "tall_rectangle",
    "triangle",
    "pentagon",
    "hexagon",
    "flat_trapezoid",
)
HALF_PI = math.pi / 2
#: Height of the longer (hanging) finger's tip, or of the object's top if that is higher,
#: below the palm in every bundled scene (fig13: "just high enough so that the longer
#: finger could not touch the support").
PALM_MARGIN = 0.01


def raw_scene(name: str) -> dict[str, Any]:
    """The bundled YAML file as plain data."""
    return yaml.safe_load((SCENES_DIR / f"{name}.yaml").read_text())


# ---------------------------------------------------------------------------------------
# Independent geometry (no grasp_env.core.geometry)
# ---------------------------------------------------------------------------------------


def fan_area_centroid(v: np.ndarray) -> tuple[float, np.ndarray]:
    """Signed area and centroid by triangulating from vertex 0."""
    area = 0.0
    moment = np.zeros(2)
    for i in range(1, len(v) - 1):
        a, b = v[i] - v[0], v[i + 1] - v[0]
        t = 0.5 * (a[0] * b[1] - a[1] * b[0])
        area += t
        moment += t * (v[0] + v[i] + v[i + 1]) / 3.0
    return area, moment / area


def width_by_projection(v: np.ndarray, n_dirs: int = 20_000) -> float:
    """Min over directions of the extent of the projection: the min distance between
    parallel supporting lines (sampled; the error is at most extent * pi / n_dirs)."""
    phi = np.linspace(0.0, math.pi, n_dirs, endpoint=False)
    proj = v @ np.stack([np.cos(phi), np.sin(phi)])
    return float((proj.max(axis=0) - proj.min(axis=0)).min())


def sliced_mass_properties(v: np.ndarray, n_rows: int = 4000) -> tuple[float, np.ndarray, float]:
    """Area, centroid and polar second moment about the centroid (per unit density) of a
    convex polygon, by the midpoint rule in y with each row's x-integral done exactly."""
    y0, y1 = v[:, 1].min(), v[:, 1].max()
    h = (y1 - y0) / n_rows
    y = y0 + h * (np.arange(n_rows) + 0.5)
    a, b = v, np.roll(v, -1, axis=0)
    xs = np.full((n_rows, len(v)), np.nan)
    for k in range(len(v)):
        if a[k, 1] == b[k, 1]:
            continue
        lo, hi = sorted((a[k, 1], b[k, 1]))
        rows = (y >= lo) & (y <= hi)
        t = (y[rows] - a[k, 1]) / (b[k, 1] - a[k, 1])
        xs[rows, k] = a[k, 0] + t * (b[k, 0] - a[k, 0])
    xl, xr = np.nanmin(xs, axis=1), np.nanmax(xs, axis=1)
    area = h * float((xr - xl).sum())
    cx = h * float(((xr**2 - xl**2) / 2).sum()) / area
    cy = h * float((y * (xr - xl)).sum()) / area
    j = h * float((((xr - cx) ** 3 - (xl - cx) ** 3) / 3 + (y - cy) ** 2 * (xr - xl)).sum())
    return area, np.array([cx, cy]), j


def inward_normals(v: np.ndarray) -> np.ndarray:
    """Unit normals of the edges v_k -> v_k+1 of a CCW polygon, pointing into it."""
    d = np.roll(v, -1, axis=0) - v
    n = np.stack([-d[:, 1], d[:, 0]], axis=1)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def tipping_moments(v: np.ndarray, n_samples: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Moments of unit frictionless contact forces on the exposed perimeter (section 2.4).

    Contacts are sampled on every edge not lying on the support and, at every vertex above
    the support, over the cone of normals between its two edges' normals. Returns the
    moments about the right and the left end of the supporting edge: a force tips the
    object about the right end (is in the right tippability region) when its moment there
    is clockwise (< 0), i.e. of the sense of the left support force; symmetrically about
    the left end with a counter-clockwise moment (> 0).
    """
    on_support = np.isclose(v[:, 1], 0.0, atol=1e-12)
    base_x = v[on_support, 0]
    r_left, r_right = np.array([base_x.min(), 0.0]), np.array([base_x.max(), 0.0])
    n_in = inward_normals(v)
    points, normals = [], []
    k_count = len(v)
    for k in range(k_count):
        nxt = (k + 1) % k_count
        if not (on_support[k] and on_support[nxt]):
            t = np.linspace(0.0, 1.0, n_samples)[:, None]
            points.append(v[k] + t * (v[nxt] - v[k]))
            normals.append(np.repeat(n_in[k][None], n_samples, axis=0))
        if not on_support[k]:
            a0 = math.atan2(n_in[k - 1, 1], n_in[k - 1, 0])
            a1 = math.atan2(n_in[k, 1], n_in[k, 0])
            da = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
            ang = a0 + da * np.linspace(0.0, 1.0, n_samples)
            points.append(np.repeat(v[k][None], n_samples, axis=0))
            normals.append(np.stack([np.cos(ang), np.sin(ang)], axis=1))
    p, n = np.concatenate(points), np.concatenate(normals)

    def moment(r: np.ndarray) -> np.ndarray:
        d = p - r
        return d[:, 0] * n[:, 1] - d[:, 1] * n[:, 0]

    return moment(r_right), moment(r_left)


def cyclic_shape_signature(v: np.ndarray) -> list[tuple[float, float]]:
    """(edge length, turning angle at its end vertex) for each edge, rounded."""
    d = np.roll(v, -1, axis=0) - v
    length = np.linalg.norm(d, axis=1)
    dn = np.roll(d, -1, axis=0)
    turn = np.arctan2(d[:, 0] * dn[:, 1] - d[:, 1] * dn[:, 0], (d * dn).sum(axis=1))
    return [(round(float(a), 9), round(float(b), 9)) for a, b in zip(length, turn, strict=True)]


def has_mirror_symmetry(v: np.ndarray) -> bool:
    """True when some reflection maps the polygon onto itself."""
    # A reflection reverses the vertex order: compare the signature with every rotation of
    # the signature of the reversed polygon.
    sig = cyclic_shape_signature(v)
    rev = cyclic_shape_signature(v[::-1].copy())
    rev = [(le, -tu) for le, tu in rev]  # reversing the order flips the sense of turning
    return any(sig == rev[s:] + rev[:s] for s in range(len(sig)))


def assert_same_scene(a: Scene, b: Scene) -> None:
    assert (a.name, a.gravity) == (b.name, b.gravity)
    assert a.palm.width == b.palm.width and a.palm.thickness == b.palm.thickness
    np.testing.assert_array_equal(a.palm.pose, b.palm.pose)
    for fa, fb in zip(a.fingers, b.fingers, strict=True):
        assert (fa.length, fa.thickness, fa.angle, fa.limits, fa.torque_limits) == (
            fb.length,
            fb.thickness,
            fb.angle,
            fb.limits,
            fb.torque_limits,
        )
    np.testing.assert_array_equal(a.object.vertices_B, b.object.vertices_B)
    np.testing.assert_array_equal(a.object.start_pose, b.object.start_pose)
    assert (a.object.mass, a.object.inertia) == (b.object.mass, b.object.inertia)


# ---------------------------------------------------------------------------------------
# Bundled scenes
# ---------------------------------------------------------------------------------------


def test_bundled_scenes_lists_every_file() -> None:
    assert bundled_scenes() == SCENE_FILES
    assert set(REQUIRED_SCENES) <= set(SCENE_FILES)


def test_scene_error_is_a_value_error() -> None:
    assert issubclass(SceneError, ValueError)


@pytest.mark.parametrize("name", SCENE_FILES, ids=SCENE_FILES)
def test_bundled_scene_loads_by_name_path_and_dict(name: str) -> None:
    path = SCENES_DIR / f"{name}.yaml"
    by_name = load_scene(name)
    assert isinstance(by_name, Scene)
    assert by_name.name == name
    assert load_scene(by_name) is by_name
    for other in (load_scene(path), load_scene(str(path)), load_scene(raw_scene(name))):
        assert_same_scene(by_name, other)
    assert Path(load_scene(path).source).resolve() == path.resolve()


@pytest.mark.parametrize("name", SCENE_FILES, ids=SCENE_FILES)
def test_bundled_scene_documents_itself(name: str) -> None:
    lines = (SCENES_DIR / f"{name}.yaml").read_text().splitlines()
    assert lines[0].startswith(f"# {name}:"), "a scene starts with a comment naming it"
    comment = lines[: next(i for i, ln in enumerate(lines) if not ln.startswith("#"))]
    assert len(comment) >= 4 and any("Exercises" in ln for ln in comment)
    assert raw_scene(name)["name"] == name


@pytest.mark.parametrize("name", SCENE_FILES, ids=SCENE_FILES)
def test_bundled_scene_start_conventions(name: str) -> None:
    """Object resting stably on y = 0, CCW; hand level, fingers hanging, nothing touching."""
    raw = raw_scene(name)
    v = np.array(raw["object"]["vertices"], dtype=float)
    area, c = fan_area_centroid(v)
    assert area > 0, "vertices are counter-clockwise"
    assert v[:, 1].min() == 0.0
    on_support = v[:, 1] == 0.0
    assert np.sum(on_support) == 2 and any(
        on_support[k] and on_support[(k + 1) % len(v)] for k in range(len(v))
    ), "the lowest edge lies on the support"
    base = v[on_support, 0]
    assert base.min() < c[0] < base.max(), "the centroid is over the base: stable at rest"

    xp, yp, thp = raw["palm"]["pose"]
    w = raw["palm"]["width"]
    assert thp == 0.0
    lengths = [f["length"] for f in raw["fingers"]]
    for f in raw["fingers"]:
        assert f["angle"] == pytest.approx(-HALF_PI, abs=1e-15)
    # Fingers hang at x = xp -+ w/2 with their bodies outside: the object is strictly inside.
    assert xp - w / 2 < v[:, 0].min() and v[:, 0].max() < xp + w / 2
    assert v[:, 1].max() < yp, "the object is lower than the palm"
    assert yp == pytest.approx(max(max(lengths), v[:, 1].max()) + PALM_MARGIN, abs=1e-12)
    tips_y = [
        yp + L * math.sin(thp + f["angle"]) for L, f in zip(lengths, raw["fingers"], strict=True)
    ]
    assert min(tips_y) > 0.0, "no finger reaches the support"


@pytest.mark.parametrize("name", SCENE_FILES, ids=SCENE_FILES)
def test_object_mass_is_density_times_area(name: str) -> None:
    raw = raw_scene(name)
    scene = load_scene(name)
    area, centroid = fan_area_centroid(np.array(raw["object"]["vertices"], dtype=float))
    if "mass" in raw["object"]:
        expected = raw["object"]["mass"]
    else:
        expected = raw["object"].get("density", 1.0) * area
    assert scene.object.mass == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(scene.object.start_pose, [*centroid, 0.0], atol=1e-12)
    palm = raw["palm"]
    assert scene.palm.mass == pytest.approx(
        palm.get("density", 1.0) * palm["width"] * palm.get("thickness", 0.15), rel=1e-12
    )
    for spec, f in zip(scene.fingers, raw["fingers"], strict=True):
        assert spec.mass == pytest.approx(
            f.get("density", 1.0) * f["length"] * f.get("thickness", 0.05), rel=1e-12
        )


@pytest.mark.parametrize("name", SCENE_FILES, ids=SCENE_FILES)
def test_object_inertia_matches_sliced_integration(name: str) -> None:
    scene = load_scene(name)
    area, centroid, j = sliced_mass_properties(
        np.array(raw_scene(name)["object"]["vertices"], float)
    )
    np.testing.assert_allclose(scene.object.start_pose[:2], centroid, atol=1e-9)
    assert scene.object.inertia == pytest.approx(scene.object.mass * j / area, rel=1e-6)


# ---------------------------------------------------------------------------------------
# The paper's section-4 set-up (Fig. 13)
# ---------------------------------------------------------------------------------------


def test_fig13_matches_the_paper_setup() -> None:
    raw = raw_scene("fig13")
    scene = load_scene("fig13")
    v = np.array(raw["object"]["vertices"], dtype=float)
    _, centroid = fan_area_centroid(v)

    assert scene.palm.width == 1.0
    assert [f.length for f in scene.fingers] == [0.6, 0.7]
    xp, yp, thp = scene.palm.pose
    assert xp == pytest.approx(centroid[0], abs=1e-12), "palm centred over the object"
    assert thp == 0.0, "palm parallel to the support"
    assert [f.angle for f in scene.fingers] == pytest.approx([-HALF_PI, -HALF_PI], abs=1e-15)
    # "just high enough so that the longer finger could not touch the support"
    tip2_y = yp + 0.7 * math.sin(thp + scene.fingers[1].angle)
    assert tip2_y == pytest.approx(PALM_MARGIN, abs=1e-12)
    assert 0.0 < tip2_y <= 0.02
    assert v[:, 1].max() < yp

    # Width 0.4 (min distance between parallel supporting lines). Sampling 20000 directions
    # overestimates a kinked minimum by at most extent * pi / 20000 < 1e-4.
    assert width_by_projection(v) == pytest.approx(0.4, abs=1e-4)

    # Masses proportional to areas; torque limits that do not matter.
    assert scene.palm.density == 1.0
    assert all(f.density == 1.0 for f in scene.fingers)
    assert raw["object"]["density"] == 1.0 and "mass" not in raw["object"]
    for f in scene.fingers:
        assert f.torque_limits[0] <= -50.0 and f.torque_limits[1] >= 50.0

    assert len(v) in (4, 5) and not has_mirror_symmetry(v), "irregular, not symmetric"


def test_fig13_object_is_tippable_from_both_sides() -> None:
    v = np.array(raw_scene("fig13")["object"]["vertices"], dtype=float)
    m_right, m_left = tipping_moments(v)
    assert (m_right < -1e-3).any(), "some contacts unload the left support contact"
    assert (m_left > 1e-3).any(), "some contacts unload the right support contact"


def test_flat_trapezoid_has_empty_tippability_regions() -> None:
    v = np.array(raw_scene("flat_trapezoid")["object"]["vertices"], dtype=float)
    m_right, m_left = tipping_moments(v)
    assert m_right.min() >= -1e-12
    assert m_left.max() <= 1e-12


def test_symmetry_check_detects_a_symmetric_polygon() -> None:
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    kite = np.array([[0, 0], [1, 0.5], [0, 2], [-1, 0.5]], dtype=float)
    assert has_mirror_symmetry(square) and has_mirror_symmetry(kite)
    assert not has_mirror_symmetry(np.array([[0, 0], [1, 0], [0.2, 0.7]], dtype=float))


# ---------------------------------------------------------------------------------------
# Mass properties against closed forms and numerical integration
# ---------------------------------------------------------------------------------------


def free_object_scene(vertices: list[list[float]], **mass: float) -> dict[str, Any]:
    """A scene dict for an object with the hand above it and the fingers spread level."""
    v = np.array(vertices, dtype=float)
    return {
        "name": "free_object",
        "palm": {"width": 1.0, "pose": [float(v[:, 0].mean()), float(v[:, 1].max()) + 0.1, 0.0]},
        "fingers": [{"length": 0.6, "angle": -math.pi}, {"length": 0.7, "angle": 0.0}],
        "object": {"vertices": vertices, **mass},
    }


RECTANGLES = [
    pytest.param(1.0, 1.0, {"density": 1.0}, id="unit-square-density-1"),
    pytest.param(1.0, 1.0, {"mass": 3.0}, id="unit-square-mass-3"),
    pytest.param(0.3, 0.5, {"density": 2.5}, id="rect-0.3x0.5-density-2.5"),
    pytest.param(2.0, 0.2, {"mass": 0.7}, id="rect-2x0.2-mass-0.7"),
]


@pytest.mark.parametrize(("a", "b", "mass_spec"), RECTANGLES)
def test_rectangle_inertia_closed_form(a: float, b: float, mass_spec: dict[str, float]) -> None:
    scene = scene_from_dict(free_object_scene([[0, 0], [a, 0], [a, b], [0, b]], **mass_spec))
    m = mass_spec.get("mass", mass_spec.get("density", 1.0) * a * b)
    assert scene.object.mass == pytest.approx(m, rel=1e-12)
    assert scene.object.inertia == pytest.approx(m * (a * a + b * b) / 12.0, rel=1e-12)
    np.testing.assert_allclose(scene.object.start_pose, [a / 2, b / 2, 0.0], atol=1e-15)


TRIANGLES = [
    pytest.param([[-0.2, 0.0], [0.2, 0.0], [0.05, 0.35]], id="triangle-scene"),
    pytest.param([[0.0, 0.0], [0.5, 0.0], [0.0, 0.3]], id="right-angled"),
    pytest.param([[0.0, 0.0], [0.6, 0.0], [0.9, 0.1]], id="obtuse-flat"),
]


@pytest.mark.parametrize("vertices", TRIANGLES)
def test_triangle_inertia_by_grid_integration(vertices: list[list[float]]) -> None:
    scene = scene_from_dict(free_object_scene(vertices, density=1.0))
    v = np.array(vertices, dtype=float)
    n = 1500
    lo, hi = v.min(axis=0), v.max(axis=0)
    gx = lo[0] + (hi[0] - lo[0]) * (np.arange(n) + 0.5) / n
    gy = lo[1] + (hi[1] - lo[1]) * (np.arange(n) + 0.5) / n
    x, y = np.meshgrid(gx, gy)
    inside = np.ones_like(x, dtype=bool)
    for k in range(3):
        (ax, ay), (bx, by) = v[k], v[(k + 1) % 3]
        inside &= (bx - ax) * (y - ay) - (by - ay) * (x - ax) >= 0
    xs, ys = x[inside], y[inside]
    cx, cy = xs.mean(), ys.mean()
    # Per unit mass: the grid's cell area cancels.
    k2_grid = float(((xs - cx) ** 2 + (ys - cy) ** 2).mean())
    assert scene.object.inertia / scene.object.mass == pytest.approx(k2_grid, rel=1e-3)
    # Closed form for a triangle about its centroid: m (a^2 + b^2 + c^2) / 36.
    sides = np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1)
    assert scene.object.inertia == pytest.approx(
        scene.object.mass * float((sides**2).sum()) / 36.0, rel=1e-12
    )


# ---------------------------------------------------------------------------------------
# Malformed scenes: each derived from fig13 by one change
# ---------------------------------------------------------------------------------------

BASE = raw_scene("fig13")
FIG13_V = BASE["object"]["vertices"]
STAR = [  # vertices 0, 2, 4, 1, 3 of a regular pentagon: every turn is a left turn
    [
        0.015 + 0.15 * math.cos(HALF_PI + 2 * math.pi * k / 5),
        0.2 + 0.15 * math.sin(HALF_PI + 2 * math.pi * k / 5),
    ]
    for k in (0, 2, 4, 1, 3)
]


def _get(d: Any, path: tuple) -> Any:
    for k in path:
        d = d[k]
    return d


def setv(path: tuple, value: Any) -> Callable[[dict], None]:
    def change(d: dict) -> None:
        _get(d, path[:-1])[path[-1]] = value

    return change


def delv(path: tuple) -> Callable[[dict], None]:
    def change(d: dict) -> None:
        del _get(d, path[:-1])[path[-1]]

    return change


def shift_object(dx: float, dy: float) -> Callable[[dict], None]:
    return setv(("object", "vertices"), [[x + dx, y + dy] for x, y in FIG13_V])


def both(*changes: Callable[[dict], None]) -> Callable[[dict], None]:
    def change(d: dict) -> None:
        for c in changes:
            c(d)

    return change


F0, F1 = ("fingers", 0), ("fingers", 1)
OV = ("object", "vertices")


def bad(
    case_id: str,
    change: Callable[[dict], None],
    field: str,
    value: str,
) -> Any:
    """A malformed scene: ``change`` applied to fig13 must raise a SceneError matching
    ``field`` (the field's name) whose message also matches ``value`` (the offending value)."""
    return pytest.param(case_id, change, field, value, id=case_id)


BAD_SCENES = [
    # -- polygon -------------------------------------------------------------------------
    bad(
        "nonconvex",
        setv(OV, [*FIG13_V[:3], [0.0, 0.1], FIG13_V[4]]),
        r"object\.vertices",
        r"\[0\.0, 0\.1\]",
    ),
    bad("clockwise", setv(OV, FIG13_V[::-1]), r"object\.vertices.*clockwise", r"\[0\.33, 0\.24\]"),
    bad(
        "repeated-adjacent",
        setv(OV, [*FIG13_V[:3], FIG13_V[2], *FIG13_V[3:]]),
        r"object\.vertices\[2\] and \[3\]",
        r"\[0\.33, 0\.24\]",
    ),
    bad(
        "repeated-closing",
        setv(OV, [*FIG13_V, FIG13_V[0]]),
        r"object\.vertices\[5\] and \[0\]",
        r"\[-0\.13, 0\.0\]",
    ),
    bad(
        "repeated-nonadjacent",
        setv(OV, [*FIG13_V, FIG13_V[1]]),
        r"object\.vertices",
        r"\[0\.15, 0\.0\]\]$",
    ),
    bad(
        "two-vertices",
        setv(OV, FIG13_V[:2]),
        r"object\.vertices.*at least 3",
        r"\[\[-0\.13, 0\.0\], \[0\.15, 0\.0\]\]",
    ),
    bad(
        "collinear",
        setv(OV, [[-0.1, 0.0], [0.0, 0.0], [0.1, 0.0]]),
        r"object\.vertices",
        r"\[0\.1, 0\.0\]",
    ),
    bad(
        "self-intersecting-star",
        setv(OV, STAR),
        r"object\.vertices",
        r"\[",
    ),
    bad(
        "vertex-three-coords",
        setv((*OV, 0), [-0.13, 0.0, 0.0]),
        r"object\.vertices\[0\]",
        r"\[-0\.13, 0\.0, 0\.0\]",
    ),
    bad("vertices-not-list", setv(OV, "square"), r"object\.vertices", r"'square'"),
    # -- non-positive sizes ---------------------------------------------------------------
    bad("palm-width-zero", setv(("palm", "width"), 0.0), r"palm\.width", r"0\.0"),
    bad("palm-width-negative", setv(("palm", "width"), -1.0), r"palm\.width", r"-1\.0"),
    bad("palm-thickness-zero", setv(("palm", "thickness"), 0), r"palm\.thickness", r"got 0"),
    bad("finger1-length-zero", setv((*F0, "length"), 0.0), r"fingers\[0\]\.length", r"0\.0"),
    bad("finger2-length-negative", setv((*F1, "length"), -0.7), r"fingers\[1\]\.length", r"-0\.7"),
    bad(
        "finger1-thickness-negative",
        setv((*F0, "thickness"), -0.05),
        r"fingers\[0\]\.thickness",
        r"-0\.05",
    ),
    bad("palm-density-zero", setv(("palm", "density"), 0.0), r"palm\.density", r"0\.0"),
    bad(
        "finger2-density-negative", setv((*F1, "density"), -1.0), r"fingers\[1\]\.density", r"-1\.0"
    ),
    bad("object-density-zero", setv(("object", "density"), 0.0), r"object\.density", r"0\.0"),
    bad(
        "object-mass-negative",
        both(delv(("object", "density")), setv(("object", "mass"), -0.2)),
        r"object\.mass",
        r"-0\.2",
    ),
    bad(
        "object-mass-zero",
        both(delv(("object", "density")), setv(("object", "mass"), 0)),
        r"object\.mass",
        r"got 0",
    ),
    bad("gravity-zero", setv(("gravity",), 0.0), r"gravity", r"0\.0"),
    bad("gravity-negative", setv(("gravity",), -9.81), r"gravity", r"-9\.81"),
    # -- placement at the start -----------------------------------------------------------
    bad(
        "object-below-support",
        shift_object(0.0, -0.05),
        r"object\.vertices.*below the support",
        r"-0\.0[45]\d*",
    ),
    bad(
        "object-overlaps-finger2",
        shift_object(0.2, 0.0),
        r"fingers\[1\].*overlaps the object",
        r"by 0\.\d+",
    ),
    bad(
        "object-overlaps-finger1",
        shift_object(-0.2, 0.0),
        r"fingers\[0\].*overlaps the object",
        r"by 0\.\d+",
    ),
    bad(
        "object-overlaps-palm",
        both(
            setv(("palm", "pose"), [BASE["palm"]["pose"][0], 0.35, 0.0]),
            setv((*F0, "angle"), -math.pi),
            setv((*F1, "angle"), 0.0),
        ),
        r"palm\.pose.*overlaps the object",
        r"by 0\.0[45]\d*",
    ),
    bad(
        "finger2-enters-support",
        setv((*F1, "length"), 0.75),
        r"fingers\[1\].*inside the support",
        r"-0\.0[45]\d*",
    ),
    bad(
        "tilted-palm-finger1-enters-support",
        setv(("palm", "pose"), [BASE["palm"]["pose"][0], 0.71, 0.3]),
        r"fingers\[0\].*inside the support",
        r"-0\.02\d*",
    ),
    bad(
        "palm-below-support",
        setv(("palm", "pose"), [3.0, -0.2, 0.0]),
        r"palm\.pose.*inside the support",
        r"-0\.2",
    ),
    # -- joint angles and limits ----------------------------------------------------------
    bad("finger1-angle-above-limit", setv((*F0, "angle"), 0.5), r"fingers\[0\]\.angle", r"0\.5"),
    bad("finger2-angle-below-limit", setv((*F1, "angle"), -4.0), r"fingers\[1\]\.angle", r"-4\.0"),
    bad(
        "finger1-limits-reversed",
        setv((*F0, "limits"), [0.0, -math.pi]),
        r"fingers\[0\]\.limits",
        r"\[0\.0, -3\.14",
    ),
    bad(
        "finger2-torque-limits-reversed",
        setv((*F1, "torque_limits"), [50.0, -50.0]),
        r"fingers\[1\]\.torque_limits",
        r"\[50\.0, -50\.0\]",
    ),
    bad(
        "finger1-limits-one-number",
        setv((*F0, "limits"), [-3.0]),
        r"fingers\[0\]\.limits",
        r"\[-3\.0\]",
    ),
    # -- NaN and infinity -----------------------------------------------------------------
    bad("palm-pose-nan", setv(("palm", "pose", 0), math.nan), r"palm\.pose\[0\]", r"nan"),
    bad("palm-pose-inf", setv(("palm", "pose", 1), math.inf), r"palm\.pose\[1\]", r"inf"),
    bad("vertex-nan", setv((*OV, 2, 1), math.nan), r"object\.vertices\[2\]\[1\]", r"nan"),
    bad("vertex-minus-inf", setv((*OV, 0, 0), -math.inf), r"object\.vertices\[0\]\[0\]", r"-inf"),
    bad("finger1-length-inf", setv((*F0, "length"), math.inf), r"fingers\[0\]\.length", r"inf"),
    bad("finger2-angle-nan", setv((*F1, "angle"), math.nan), r"fingers\[1\]\.angle", r"nan"),
    bad("gravity-nan", setv(("gravity",), math.nan), r"gravity", r"nan"),
    bad(
        "finger1-limit-nan",
        setv((*F0, "limits"), [math.nan, 0.0]),
        r"fingers\[0\]\.limits\[0\]",
        r"nan",
    ),
    bad(
        "palm-width-int-too-big-for-float",
        setv(("palm", "width"), 10**400),
        r"palm\.width",
        r"1000",
    ),
    # -- wrong types ----------------------------------------------------------------------
    bad("palm-width-string", setv(("palm", "width"), "1.0"), r"palm\.width", r"'1\.0'"),
    bad("gravity-string", setv(("gravity",), "9.81 m/s^2"), r"gravity", r"'9\.81 m/s\^2'"),
    bad("vertex-string", setv((*OV, 1), "0.15, 0.0"), r"object\.vertices\[1\]", r"'0\.15, 0\.0'"),
    bad("finger1-angle-bool", setv((*F0, "angle"), True), r"fingers\[0\]\.angle", r"True"),
    bad("object-density-bool", setv(("object", "density"), True), r"object\.density", r"True"),
    bad("palm-pose-entry-bool", setv(("palm", "pose", 2), False), r"palm\.pose\[2\]", r"False"),
    bad("finger2-length-none", setv((*F1, "length"), None), r"fingers\[1\]\.length", r"None"),
    bad("name-not-string", setv(("name",), 13), r"name", r"13"),
    bad("palm-not-mapping", setv(("palm",), None), r"palm", r"None"),
    bad("finger-not-mapping", setv(F0, 0.6), r"fingers\[0\]", r"0\.6"),
    # -- wrong lengths --------------------------------------------------------------------
    bad(
        "palm-pose-two-numbers",
        setv(("palm", "pose"), [0.0, 0.71]),
        r"palm\.pose",
        r"\[0\.0, 0\.71\]",
    ),
    bad(
        "palm-pose-four-numbers",
        setv(("palm", "pose"), [0.0, 0.71, 0.0, 0.0]),
        r"palm\.pose",
        r"\[0\.0, 0\.71, 0\.0, 0\.0\]",
    ),
    bad("palm-pose-scalar", setv(("palm", "pose"), 0.71), r"palm\.pose", r"0\.71"),
    # -- unknown and missing keys ---------------------------------------------------------
    bad("unknown-top-key", setv(("friction",), 0.3), r"scene: unknown key", r"'friction'"),
    bad("unknown-palm-key", setv(("palm", "mass"), 1.0), r"palm: unknown key", r"'mass'"),
    bad(
        "unknown-finger-key", setv((*F1, "radius"), 0.02), r"fingers\[1\]: unknown key", r"'radius'"
    ),
    bad(
        "unknown-object-key", setv(("object", "colour"), "red"), r"object: unknown key", r"'colour'"
    ),
    bad("missing-object", delv(("object",)), r"scene: missing key", r"'object'"),
    bad("missing-fingers", delv(("fingers",)), r"scene: missing key", r"'fingers'"),
    bad("missing-palm", delv(("palm",)), r"scene: missing key", r"'palm'"),
    bad("missing-palm-pose", delv(("palm", "pose")), r"palm: missing key", r"'pose'"),
    bad("missing-palm-width", delv(("palm", "width")), r"palm: missing key", r"'width'"),
    bad("missing-finger1-length", delv((*F0, "length")), r"fingers\[0\]: missing key", r"'length'"),
    bad("missing-finger2-angle", delv((*F1, "angle")), r"fingers\[1\]: missing key", r"'angle'"),
    bad("missing-object-vertices", delv(OV), r"object: missing key", r"'vertices'"),
    # -- ranges (scene module docstring), degrees, edges below the contact tolerance -----
    bad("palm-width-below-range", setv(("palm", "width"), 1e-7), r"palm\.width", r"1e-07"),
    bad("palm-width-above-range", setv(("palm", "width"), 1e7), r"palm\.width", r"10000000\.0"),
    bad(
        "palm-thickness-relative",
        setv(("palm", "thickness"), 2000.0),
        r"palm\.thickness must be within \[0\.001, 1000\] x palm\.width",
        r"2000\.0",
    ),
    bad(
        "palm-thickness-default-on-a-tiny-palm",
        both(setv(("palm", "width"), 1e-4), delv(("palm", "thickness"))),
        r"palm\.thickness .*palm\.width \(default\)",
        r"0\.15",
    ),
    bad(
        "finger1-thickness-below-range",
        setv((*F0, "thickness"), 1e-4),
        r"fingers\[0\]\.thickness",
        r"0\.0001",
    ),
    bad(
        "finger2-length-above-range", setv((*F1, "length"), 1e4), r"fingers\[1\]\.length", r"10000"
    ),
    bad(
        "palm-pose-far-away",
        setv(("palm", "pose", 0), 2e4),
        r"palm\.pose\[0\].*10000 x palm\.width",
        r"20000\.0",
    ),
    bad("vertex-far-away", shift_object(2e4, 0.0), r"object\.vertices\[0\]\[0\]", r"19999\.87"),
    bad(
        "object-below-size-range",
        setv(OV, [[x * 1e-4, y * 1e-4] for x, y in FIG13_V]),
        r"object\.vertices: the object's size",
        r"6\.3\d*e-05",
    ),
    bad(
        "object-above-size-range",
        setv(OV, [[x * 2e3, y * 2e3] for x, y in FIG13_V]),
        r"object\.vertices: the object's size",
        r"1260\.0",
    ),
    bad("gravity-below-range", setv(("gravity",), 1e-10), r"gravity", r"1e-10"),
    bad("gravity-above-range", setv(("gravity",), 1e10), r"gravity", r"10000000000\.0"),
    bad("palm-density-below-range", setv(("palm", "density"), 1e-10), r"palm\.density", r"1e-10"),
    bad(
        "finger1-density-above-range",
        setv((*F0, "density"), 1e10),
        r"fingers\[0\]\.density",
        r"10000000000\.0",
    ),
    bad(
        "object-mass-too-light-for-its-area",
        both(delv(("object", "density")), setv(("object", "mass"), 1e-11)),
        r"object\.mass.*mean density",
        r"1e-11",
    ),
    bad(
        "object-mass-too-heavy-for-its-area",
        both(delv(("object", "density")), setv(("object", "mass"), 1e9)),
        r"object\.mass.*mean density",
        r"1000000000\.0",
    ),
    bad(
        "finger1-torque-limit-above-range",
        setv((*F0, "torque_limits"), [-1e10, 50.0]),
        r"fingers\[0\]\.torque_limits\[0\].*x object weight x palm\.width",
        r"-10000000000\.0",
    ),
    bad("palm-width-huge", setv(("palm", "width"), 1e308), r"palm\.width", r"1e\+308"),
    bad("object-density-huge", setv(("object", "density"), 1e200), r"object\.density", r"1e\+200"),
    bad(
        "object-mass-subnormal",
        both(delv(("object", "density")), setv(("object", "mass"), 1e-320)),
        r"object\.mass",
        r"1e-320",
    ),
    bad(
        "vertex-huge",
        setv(OV, [[x * 1e200, y * 1e200] for x, y in FIG13_V]),
        r"object\.vertices\[0\]\[0\]",
        r"-1\.3e\+199",
    ),
    bad(
        "finger1-angle-degrees",
        both(setv((*F0, "angle"), -90.0), setv((*F0, "limits"), [-180.0, 0.0])),
        r"fingers\[0\]\.limits\[0\].*degrees",
        r"-180\.0",
    ),
    bad("finger2-angle-degrees", setv((*F1, "angle"), -90), r"fingers\[1\]\.angle", r"-90"),
    bad("palm-angle-degrees", setv(("palm", "pose", 2), 30.0), r"palm\.pose\[2\]", r"30\.0"),
    bad(
        "edge-below-contact-tol",
        setv(OV, [*FIG13_V[:2], [0.15 + 2e-9, 2e-9], *FIG13_V[2:]]),
        r"object\.vertices\[1\] and \[2\].*contact tolerances",
        r"2\.8\d*e-09 apart",
    ),
    # -- finger count, mass and density ---------------------------------------------------
    bad(
        "three-fingers",
        setv(("fingers",), [*BASE["fingers"], {"length": 0.65, "angle": -HALF_PI}]),
        r"fingers.*exactly two",
        r"'length': 0\.65",
    ),
    bad(
        "one-finger",
        setv(("fingers",), BASE["fingers"][:1]),
        r"fingers.*exactly two",
        r"'length': 0\.6",
    ),
    bad(
        "fingers-mapping",
        setv(("fingers",), {"left": BASE["fingers"][0]}),
        r"fingers.*exactly two",
        r"'left'",
    ),
    bad(
        "density-and-mass",
        setv(("object", "mass"), 0.5),
        r"object.*density.*mass",
        r"0\.5",
    ),
]


@pytest.mark.parametrize(("case_id", "change", "field", "value"), BAD_SCENES)
def test_bad_scene_is_refused(case_id: str, change: Callable, field: str, value: str) -> None:
    d = copy.deepcopy(BASE)
    change(d)
    with pytest.raises(SceneError, match=field) as info:
        load_scene(d)
    # Some messages show numpy scalars as np.float64(x) (numpy >= 2 repr); read them as x.
    message = re.sub(r"np\.float64\(([^()]*)\)", r"\1", str(info.value))
    assert re.search(value, message), f"{case_id}: value not in {str(info.value)!r}"


def test_bad_scene_cases_change_a_valid_scene() -> None:
    load_scene(copy.deepcopy(BASE))  # the base itself is valid
    assert len(BAD_SCENES) >= 25
    assert len({p.id for p in BAD_SCENES}) == len(BAD_SCENES)


def _fig13_weight() -> float:
    return load_scene(copy.deepcopy(BASE)).object_weight


def _all_densities(rho: float) -> Callable[[dict], None]:
    def change(d: dict) -> None:
        for body in (d["palm"], *d["fingers"], d["object"]):
            body["density"] = rho

    return change


#: fig13's torque limits (50) exceed MAX_TORQUE object weights x palm widths once the weight
#: is 1e-9 times smaller: those scenes leave the torques unlimited.
UNLIMITED = both(delv((*F0, "torque_limits")), delv((*F1, "torque_limits")))

RANGE_ENDS = {
    "gravity-lowest": both(setv(("gravity",), scene_mod.GRAVITY_RANGE[0]), UNLIMITED),
    "gravity-highest": setv(("gravity",), scene_mod.GRAVITY_RANGE[1]),
    "densities-lowest": both(_all_densities(scene_mod.DENSITY_RANGE[0]), UNLIMITED),
    "densities-highest": _all_densities(scene_mod.DENSITY_RANGE[1]),
    "thinnest-finger": setv((*F0, "thickness"), scene_mod.LENGTH_RANGE[0]),
    "torque-limits-at-bound": setv(
        (*F1, "torque_limits"), [-0.999e9 * _fig13_weight(), 0.999e9 * _fig13_weight()]
    ),
    "far-along-x": both(
        setv(("palm", "pose", 0), 0.999 * scene_mod.MAX_COORDINATE),
        shift_object(0.999 * scene_mod.MAX_COORDINATE - BASE["palm"]["pose"][0], 0.0),
    ),
}


@pytest.mark.parametrize("change", RANGE_ENDS.values(), ids=RANGE_ENDS.keys())
def test_range_ends_are_accepted(change: Callable[[dict], None]) -> None:
    """Scenes at the ends of the documented ranges load (the palm width's ends are run in
    tests/sim/test_invariance.py)."""
    d = copy.deepcopy(BASE)
    change(d)
    load_scene(d)


def test_infinite_torque_limits_are_accepted() -> None:
    d = copy.deepcopy(BASE)
    d["fingers"][0]["torque_limits"] = [-math.inf, math.inf]
    assert load_scene(d).fingers[0].torque_limits == (-math.inf, math.inf)


# ---------------------------------------------------------------------------------------
# Bad names, paths and files
# ---------------------------------------------------------------------------------------


def test_unknown_bundled_name_is_refused() -> None:
    with pytest.raises(SceneError, match=r"^not a bundled scene: 'fig14';") as info:
        load_scene("fig14")
    assert all(name in str(info.value) for name in SCENE_FILES), "it lists the bundled scenes"
    assert isinstance(info.value, ValueError)
    import gymnasium as gym

    with pytest.raises(ValueError, match=r"^scene 'fig14': not a bundled scene: 'fig14';"):
        gym.make("FrictionlessGrasp-v0", scene="fig14")
    with pytest.raises(SceneError, match=r"^not a bundled scene: '';"):
        load_scene("")


def test_a_non_convex_polygon_is_refused_at_the_vertex_at_fault() -> None:
    d = copy.deepcopy(BASE)
    d["object"]["vertices"] = [[0.0, 0.0], [0.2, 0.0], [0.1, 0.02], [0.2, 0.1], [0.0, 0.1]]
    with pytest.raises(SceneError, match=r"turn right at vertex \[2\] \[0\.1, 0\.02\]"):
        load_scene(d)


def test_points_closer_than_the_tolerance_are_not_said_to_repeat() -> None:
    """Adjacent points 1e-12 apart in a unit polygon are refused as closer than the
    tolerance (1e-9 of its extent), showing both points, not as one point repeated."""
    from grasp_env.mechanics.width import object_width

    v = [[0.0, 0.0], [1.0, 0.0], [1.0, 1e-12], [0.0, 1e-12]]
    with pytest.raises(SceneError) as info:
        object_width(v)
    msg = str(info.value)
    assert msg.startswith("scene_or_vertices[1] and [2] ([1.0, 0.0], [1.0, 1e-12]) are 1e-12 apart")
    assert "tolerance of 1e-09 x the polygon's extent = 1e-09" in msg
    assert "repeat" not in msg


# A string without a path separator or a .yaml/.yml suffix is a bundled name, whatever the
# working directory holds; a separator, a suffix or an os.PathLike makes it a file.


def test_bundled_name_ignores_a_directory_of_that_name(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fig13").mkdir()  # e.g. left by `python -m agents.scripted --out fig13`
    scene = load_scene("fig13")
    assert scene.name == "fig13"
    assert Path(scene.source).resolve() == (SCENES_DIR / "fig13.yaml").resolve()
    with pytest.raises(SceneError, match=r"scene file 'fig13' cannot be read"):
        load_scene(Path("fig13"))  # a Path is a path: here a directory


def test_bundled_name_ignores_a_file_of_that_name(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fig13").write_text((SCENES_DIR / "square.yaml").read_text())
    assert load_scene("fig13").name == "fig13"
    assert load_scene(Path("fig13")).name == "square"
    assert load_scene("./fig13").name == "square"


@pytest.mark.parametrize(
    "spec",
    [Path("fig13.yaml"), "fig13.yaml", "fig13.yml", "./fig13.yaml", "FIG13.YAML"],
    ids=["Path", "yaml-suffix", "yml-suffix", "dot-slash", "upper-case-suffix"],
)
def test_path_spec_reads_the_working_directory(tmp_path, monkeypatch, spec) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / str(spec)).write_text((SCENES_DIR / "square.yaml").read_text())
    scene = load_scene(spec)
    assert scene.name == "square"
    assert Path(scene.source).resolve() == (tmp_path / str(spec)).resolve()


@pytest.mark.parametrize("spec", [Path("fig13"), "fig13.yaml", "./fig13", "./x.yaml"], ids=str)
def test_missing_path_is_not_looked_up_among_bundled_scenes(tmp_path, monkeypatch, spec) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SceneError, match=r"scene file .* cannot be read"):
        load_scene(spec)


def test_relative_path_with_separator(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.yaml").write_text((SCENES_DIR / "triangle.yaml").read_text())
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "fig13").write_text((SCENES_DIR / "hexagon.yaml").read_text())
    assert load_scene("./x.yaml").name == "triangle"
    assert load_scene("sub/fig13").name == "hexagon"


def test_load_scene_documents_the_name_rule() -> None:
    doc = load_scene.__doc__
    assert "separator" in doc and ".yaml" in doc and "PathLike" in doc


def test_bundled_scenes_are_package_data() -> None:
    """The scenes live inside the package (found through importlib.resources), so an
    installed wheel has them too; pyproject.toml declares them as package data."""
    folder = importlib.resources.files("grasp_env").joinpath("scenes")
    assert sorted(p.name for p in folder.iterdir() if p.name.endswith(".yaml")) == [
        f"{name}.yaml" for name in SCENE_FILES
    ]
    root = Path(__file__).resolve().parents[2]
    package_data = re.search(
        r"^\[tool\.setuptools\.package-data\]\n(?:#.*\n)*grasp_env = \[(.*)\]$",
        (root / "pyproject.toml").read_text(),
        re.MULTILINE,
    )
    assert package_data and '"scenes/*.yaml"' in package_data.group(1)
    assert not (root / "configs" / "scenes").exists()


def test_missing_path_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "missing.yaml"
    with pytest.raises(SceneError, match=r"scene file .* cannot be read") as info:
        load_scene(path)
    assert str(path) in str(info.value)


def test_directory_path_is_refused(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match=r"scene file .* cannot be read"):
        load_scene(tmp_path)


@pytest.mark.parametrize("spec", [42, None, 1.5, ["fig13"]], ids=["int", "none", "float", "list"])
def test_spec_of_wrong_type_is_refused(spec: Any) -> None:
    with pytest.raises(SceneError, match=r"scene must be a bundled name, a path or a dict"):
        load_scene(spec)


BAD_FILES = [
    pytest.param(
        "palm: [1.0, 2.0\nfingers: x\n", r"scene file .* is not valid YAML", id="unclosed-bracket"
    ),
    pytest.param(
        "palm:\n  width: 1.0\n\tpose: [0, 1, 0]\n",
        r"scene file .* is not valid YAML",
        id="tab-indent",
    ),
    pytest.param("", r"scene must be a mapping, got None", id="empty-file"),
    pytest.param(
        "- fig13\n- square\n", r"scene must be a mapping, got \['fig13', 'square'\]", id="list"
    ),
    pytest.param(
        "!!python/object:os.system {}\n", r"scene file .* is not valid YAML", id="python-tag"
    ),
]


@pytest.mark.parametrize(("text", "pattern"), BAD_FILES)
def test_unparsable_yaml_file_is_refused(tmp_path: Path, text: str, pattern: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(SceneError, match=pattern) as info:
        load_scene(path)
    if "YAML" in pattern:
        assert str(path) in str(info.value)


def test_non_utf8_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: caf\u00e9\n".encode("latin-1"))
    with pytest.raises(SceneError, match=r"scene file .*latin1\.yaml"):
        load_scene(path)


YAML_EDITS = [
    pytest.param(
        "  width: 1.0", "  width: .nan", r"palm\.width must be finite, got nan", id="nan-width"
    ),
    pytest.param(
        "  - {length: 0.6",
        "  - {length: .inf",
        r"fingers\[0\]\.length must be finite, got inf",
        id="inf-length",
    ),
    pytest.param(
        "pose: [0.014953080375357005",
        "pose: [.nan",
        r"palm\.pose\[0\] must be finite, got nan",
        id="nan-pose",
    ),
    # YAML 1.1 reads these as 981, 90 and 16; the loader, following YAML 1.2, as strings.
    pytest.param(
        "gravity: 9.81", "gravity: 9_81", r"gravity must be a number, got '9_81'", id="underscore"
    ),
    pytest.param(
        "gravity: 9.81", "gravity: 1:30", r"gravity must be a number, got '1:30'", id="sexagesimal"
    ),
    pytest.param(
        "gravity: 9.81", "gravity: 0x10", r"gravity must be a number, got '0x10'", id="hex"
    ),
]


@pytest.mark.parametrize(("old", "new", "pattern"), YAML_EDITS)
def test_bad_number_in_yaml_file_is_refused(
    tmp_path: Path, old: str, new: str, pattern: str
) -> None:
    text = (SCENES_DIR / "fig13.yaml").read_text()
    assert text.count(old) == 1
    path = tmp_path / "edited.yaml"
    path.write_text(text.replace(old, new))
    with pytest.raises(SceneError, match=pattern):
        load_scene(path)


@pytest.mark.parametrize(
    ("text", "value"),
    [("1e1", 10.0), ("1.5E+1", 15.0), ("010", 10.0), ("+9.81", 9.81), ("9.", 9.0)],
    ids=["exponent-no-dot", "exponent", "leading-zero", "plus-sign", "trailing-dot"],
)
def test_yaml_numbers_are_read_as_yaml_1_2(tmp_path: Path, text: str, value: float) -> None:
    # YAML 1.1 (PyYAML's default) reads 1e1 as the string '1e1' and 010 as the octal 8.
    path = tmp_path / "edited.yaml"
    path.write_text(
        (SCENES_DIR / "fig13.yaml").read_text().replace("gravity: 9.81", f"gravity: {text}")
    )
    assert load_scene(path).gravity == value


@pytest.mark.parametrize(
    ("old", "new", "pattern"),
    [
        pytest.param(
            "fingers:",
            "palm: {width: 2.0, pose: [0.0, 1.0, 0.0]}\nfingers:",
            r"duplicate key 'palm' on line 29 \(first on line 24\)",
            id="top-level-block",
        ),
        pytest.param(
            "  density: 1.0\nfingers:",
            "  density: 1.0\n  width: 2.0\nfingers:",
            r"duplicate key 'width' on line 29 \(first on line 25\)",
            id="nested",
        ),
        pytest.param(
            "{length: 0.6,",
            "{length: 0.6, length: 0.5,",
            r"duplicate key 'length' on line 30 \(first on line 30\)",
            id="flow-mapping",
        ),
    ],
)
def test_duplicate_yaml_key_is_refused(tmp_path: Path, old: str, new: str, pattern: str) -> None:
    text = (SCENES_DIR / "fig13.yaml").read_text()
    assert text.count(old) == 1
    path = tmp_path / "duplicate.yaml"
    path.write_text(text.replace(old, new))
    with pytest.raises(SceneError, match=rf"scene file .*duplicate\.yaml': {pattern}"):
        load_scene(path)


LAUGHS = "\n".join(
    ["description:", "  - &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    + [f"  - &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
)


@pytest.mark.parametrize(
    ("old", "new", "pattern"),
    [
        pytest.param(
            "gravity: &g 9.81",
            "gravity: !!bool maybe",
            r" is not valid YAML: 'maybe' is not a valid !!bool\n.*line 23",
            id="bool-tag",
        ),
        pytest.param(
            "gravity: &g 9.81",
            "gravity: !!timestamp notadate",
            r" is not valid YAML: 'notadate' is not a valid !!timestamp\n.*line 23",
            id="timestamp-tag",
        ),
        pytest.param(
            "gravity: &g 9.81",
            "gravity: !!float abc",
            r" is not valid YAML: 'abc' is not a valid !!float\n.*line 23",
            id="float-tag",
        ),
        pytest.param(
            "gravity: &g 9.81",
            "gravity: " + "[" * 5000 + "]" * 5000,
            r": values nested more than 32 levels deep on line 23$",
            id="nested-5000-deep",
        ),
        pytest.param(
            "  density: 1.0\nfingers:",
            "  density: *g\nfingers:",
            r": alias \*g on line 28: scene files may not use aliases",
            id="alias",
        ),
        pytest.param(
            'description: "Section 4',
            LAUGHS + '\nx: "Section 4',  # 9**9 lols if expanded
            r": alias \*a0 on line 24: scene files may not use aliases",
            id="billion-laughs",
        ),
    ],
)
def test_refused_yaml_is_a_scene_error_naming_file_and_line(
    tmp_path: Path, old: str, new: str, pattern: str
) -> None:
    """Tags on values they cannot hold, nesting past the recursion limit and aliases (whose
    expansion a few levels deep is exponential) are refused naming the file and the line;
    the anchor ``&g`` alone is kept."""
    text = (SCENES_DIR / "fig13.yaml").read_text().replace("gravity: 9.81", "gravity: &g 9.81")
    assert text.count(old) == 1
    path = tmp_path / "tagged.yaml"
    path.write_text(text.replace(old, new))
    with pytest.raises(SceneError, match=r"(?s)^scene file '.*tagged\.yaml'" + pattern):
        load_scene(path)
    path.write_text(text)
    assert load_scene(path).gravity == 9.81


@pytest.mark.parametrize("spec", ["a\0b.yaml", Path("a\0b")], ids=["str", "Path"])
def test_a_path_with_a_nul_byte_is_refused(spec: str | Path) -> None:
    with pytest.raises(SceneError, match=r"scene file 'a\\x00b.*' cannot be read: .*null byte"):
        load_scene(spec)


def test_scene_to_dict_round_trips_one_sided_torque_limits() -> None:
    from grasp_env.envs.shapes import scene_to_dict

    d = scene_to_dict(load_scene("fig13"))
    d["fingers"][0]["torque_limits"] = [-math.inf, 50.0]
    back = load_scene(scene_to_dict(load_scene(d)))
    assert back.fingers[0].torque_limits == (-math.inf, 50.0)
