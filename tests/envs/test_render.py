"""Headless rendering: the shared pygame renderer and the environment's render modes."""

from __future__ import annotations

import dataclasses
import pickle
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from image_checks import ink_runs

import grasp_env
from grasp_env.core import geometry as geo
from grasp_env.envs.frictionless_grasp import FrictionlessGraspEnv
from grasp_env.render import (
    BACKGROUND,
    CONTACT_COLOR,
    FINGER_COLOR,
    FORCE_COLOR,
    OBJECT_COLOR,
    PALM_COLOR,
    SUPPORT_COLOR,
    Renderer,
    scene_bounds,
    workspace_bounds,
)


def _pixels_of(frame: np.ndarray, color) -> int:
    return int(np.all(frame == np.array(color, dtype=np.uint8), axis=-1).sum())


@pytest.fixture(scope="module")
def grasped_state():
    """fig13 with both fingers on the object (contacts with positive forces)."""
    sim = grasp_env.Simulator("fig13")
    state = sim.reset()
    for _ in range(12):
        state = sim.move_hand(state, fingers=state.finger_angles + np.array([0.05, -0.05]))
    assert any(c.body.startswith("finger") and c.force > 0 for c in state.contacts)
    return state


def test_import_does_not_import_pygame():
    code = "import sys, grasp_env; assert 'pygame' not in sys.modules, 'pygame imported'"
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize("size", [(640, 480), (200, 320)], ids=["640x480", "200x320"])
def test_frame_shape_and_content(grasped_state, size):
    renderer = Renderer(*size)
    try:
        frame = renderer.draw(grasped_state, text="step 12 | form closure")
    finally:
        renderer.close()
    assert frame.shape == (size[1], size[0], 3)
    assert frame.dtype == np.uint8
    # The object's centroid pixel shows the object, not the background.
    x, y = renderer.to_pixels(grasped_state.object_pose[:2]).astype(int)
    assert tuple(frame[y, x]) == OBJECT_COLOR != BACKGROUND
    assert _pixels_of(frame, OBJECT_COLOR) > 100
    assert _pixels_of(frame, CONTACT_COLOR) > 0
    assert _pixels_of(frame, FORCE_COLOR) > 0


def test_world_to_pixel_map_is_y_up_and_isotropic(grasped_state):
    renderer = Renderer(400, 300, world_bounds=(-1.0, 1.0, -0.5, 1.0))
    renderer._fit(grasped_state)
    p = renderer.to_pixels(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    dx, dy = p[1] - p[0], p[2] - p[0]
    assert dx[0] > 0 and dy[1] < 0  # x right, y up (pixel rows grow downwards)
    assert abs(dx[0]) == pytest.approx(abs(dy[1]))
    # The requested box is inside the image, below the text band.
    corners = renderer.to_pixels(np.array([[-1.0, -0.5], [1.0, 1.0]]))
    assert np.all(corners[:, 0] >= -1e-9) and np.all(corners[:, 0] <= 400 + 1e-9)
    assert np.all(corners[:, 1] >= renderer.band - 1e-9) and np.all(corners[:, 1] <= 300 + 1e-9)


def test_scene_bounds_contain_hand_and_object():
    scene = grasp_env.load_scene("fig13")
    x0, x1, y0, y1 = scene_bounds(scene)
    for poly in grasp_env.core.kinematics.hand_polygons_W(scene, scene.initial_hand):
        assert poly[:, 0].min() > x0 and poly[:, 0].max() < x1
        assert poly[:, 1].min() >= y0 and poly[:, 1].max() < y1
    v = scene.object.vertices_W0
    assert v[:, 0].min() > x0 and v[:, 0].max() < x1 and y0 < 0 < v[:, 1].max() < y1


def test_workspace_bounds_cover_the_fingers_closing_range():
    scene = grasp_env.load_scene("fig13")
    x0, x1, y0, y1 = workspace_bounds(scene)
    h = scene.initial_hand.copy()
    for q in np.linspace(-np.pi / 2, 0.0, 9):  # finger 1 closing, finger 2 mirrored
        h[3:] = (q, -np.pi - q)
        for poly in grasp_env.core.kinematics.hand_polygons_W(scene, h):
            assert poly[:, 0].min() > x0 and poly[:, 0].max() < x1
            assert poly[:, 1].min() > y0 and poly[:, 1].max() < y1
    # Tighter than the fingers' whole range (which reaches out to the palm's level).
    assert x1 - x0 < 2.0 * scene.palm.width


def _body_rows(frame: np.ndarray) -> tuple[int, int]:
    """First and last pixel row showing a body (palm, finger or object)."""
    body = np.zeros(frame.shape[:2], bool)
    for color in (PALM_COLOR, FINGER_COLOR, OBJECT_COLOR):
        body |= np.all(frame == np.array(color, np.uint8), axis=-1)
    rows = np.nonzero(body.any(axis=1))[0]
    return int(rows.min()), int(rows.max())


def test_env_frames_are_framed_on_the_hand_and_object():
    env = FrictionlessGraspEnv(render_mode="rgb_array")
    env.reset(seed=0)
    frames = [env.render()]
    view = env._renderer.view()
    for _ in range(3):
        for _ in range(5):
            env.step(np.array([1.0, 1.0], dtype=np.float32))
        frames.append(env.render())
        assert env._renderer.view() == view  # the view holds still within the episode
    env.close()
    for k, frame in enumerate(frames):
        assert frame.shape == (480, 640, 3)
        top, bottom = _body_rows(frame)
        # the bodies fill a good share of the height (the hand alone once the object is held)
        assert (bottom - top) / 480 > (0.55 if k == 0 else 0.45), k
        assert top > Renderer(640, 480).band  # none is cut off under the text band
        # the support stays visible along the bottom
        assert np.all(frame[-1] == np.array(SUPPORT_COLOR, np.uint8))
    assert not np.array_equal(frames[0], frames[-1])


def test_view_refits_when_a_body_leaves_it(grasped_state):
    renderer = Renderer(320, 240)
    renderer.draw(grasped_state)
    view = renderer.view()
    scene = grasped_state.scene
    assert view == pytest.approx(renderer.view())
    moved = dataclasses.replace(
        grasped_state,
        hand=grasped_state.hand + np.array([3.0 * scene.palm.width, 0.0, 0.0, 0.0, 0.0]),
    )
    renderer.draw(moved)
    renderer.close()
    x0, x1, y0, y1 = renderer.view()
    assert renderer.view() != view
    for poly in grasp_env.core.kinematics.hand_polygons_W(scene, moved.hand):
        assert x0 <= poly[:, 0].min() and poly[:, 0].max() <= x1
        assert y0 <= poly[:, 1].min() and poly[:, 1].max() <= y1


def test_legend_shows_every_mark(grasped_state):
    renderer = Renderer(640, 480)
    strip = renderer.legend()
    narrow = renderer.legend(300)
    renderer.close()
    assert strip.shape[1] == 640 and narrow.shape[1] == 300
    assert narrow.shape[0] > strip.shape[0]  # wrapped onto more rows
    for color in (SUPPORT_COLOR, PALM_COLOR, FINGER_COLOR, OBJECT_COLOR, CONTACT_COLOR):
        assert _pixels_of(strip, color) > 0, color
    assert _pixels_of(strip, FORCE_COLOR) > 0
    assert min(ink_runs(strip)) >= 10


def test_text_is_readable_at_the_default_size():
    renderer = Renderer(640, 480)
    line = renderer.text_image(["fig13 | step 18 | form closure | y* = 1.49 W"], 640)
    renderer.close()
    assert renderer.font_size >= 20
    assert ink_runs(line) and ink_runs(line)[0] >= 14


def test_text_and_force_scale_change_the_frame(grasped_state):
    renderer = Renderer(320, 240)
    plain = renderer.draw(grasped_state)
    text = renderer.draw(grasped_state, text="y* = 1.23 W")
    long = renderer.draw(grasped_state, force_scale=1.0)
    renderer.close()
    assert np.any(plain != text)
    assert _pixels_of(long, FORCE_COLOR) > _pixels_of(plain, FORCE_COLOR)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"width": 0}, "width"),
        ({"height": 2.5}, "height"),
        ({"font_size": 0}, "font_size"),
        ({"world_bounds": (1.0, 0.0, 0.0, 1.0)}, "world_bounds"),
        ({"world_bounds": (0.0, 1.0, 0.0, np.nan)}, "world_bounds"),
    ],
    ids=["zero-width", "float-height", "zero-font", "inverted-bounds", "nan-bounds"],
)
def test_renderer_refuses_bad_arguments(kwargs, name):
    with pytest.raises(ValueError, match=name):
        Renderer(**kwargs)


def test_renderer_pickles_after_drawing(grasped_state):
    renderer = Renderer(160, 120)
    frame = renderer.draw(grasped_state)
    copy = pickle.loads(pickle.dumps(renderer))
    assert np.array_equal(copy.draw(grasped_state), frame)
    copy.close()
    renderer.close()


def test_object_pixels_follow_the_object_pose(grasped_state):
    renderer = Renderer(320, 240)
    frame = renderer.draw(grasped_state)
    renderer.close()
    obj_W = geo.transform(grasped_state.object_pose, grasped_state.scene.object.vertices_B)
    box = renderer.to_pixels(obj_W)
    ys, xs = np.nonzero(np.all(frame == np.array(OBJECT_COLOR, dtype=np.uint8), axis=-1))
    assert xs.min() >= box[:, 0].min() - 1 and xs.max() <= box[:, 0].max() + 1
    assert ys.min() >= box[:, 1].min() - 1 and ys.max() <= box[:, 1].max() + 1


# ---------------------------------------------------------------------- env render modes
def test_env_rgb_array_frames():
    env = FrictionlessGraspEnv(render_mode="rgb_array", render_width=240, render_height=180)
    env.reset(seed=0)
    frames = [env.render()]
    for _ in range(3):
        env.step(np.array([1.0, 1.0], dtype=np.float32))
        frames.append(env.render())
    for frame in frames:
        assert frame.shape == (180, 240, 3) and frame.dtype == np.uint8
        assert _pixels_of(frame, OBJECT_COLOR) > 50
        assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3
    # Picklable after rendering; the copy renders the same frame.
    copy = pickle.loads(pickle.dumps(env))
    assert np.array_equal(copy.render(), frames[-1])
    copy.close()
    env.close()
    assert env._renderer is None


def test_env_without_render_mode_creates_no_renderer():
    env = FrictionlessGraspEnv()
    env.reset(seed=0)
    env.step(env.action_space.sample())
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None
    assert env._renderer is None
    assert "grasp_env.render" not in sys.modules or env._renderer is None
    env.close()


def test_env_human_mode_headless():
    env = FrictionlessGraspEnv(render_mode="human", render_width=160, render_height=120)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.reset(seed=0)
        assert env.render() is None
        env.step(np.zeros(2, dtype=np.float32))
    env.close()


def test_record_video_writes_an_mp4_headless(tmp_path):
    """gymnasium's RecordVideo (MoviePy, in the viz extra) records an episode headless."""
    pytest.importorskip("moviepy", reason="the viz extra installs moviepy")
    import gymnasium as gym
    from gymnasium.wrappers import RecordVideo

    folder = tmp_path / "videos"
    env = gym.make(
        "FrictionlessGrasp-v0",
        render_mode="rgb_array",
        render_width=160,
        render_height=120,
        max_episode_steps=12,
    )
    env = RecordVideo(env, video_folder=str(folder), name_prefix="fig13")
    env.reset(seed=0)
    env.action_space.seed(0)
    truncated = terminated = False
    while not (terminated or truncated):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
    env.close()
    (video,) = folder.glob("*.mp4")
    assert video.name == "fig13-episode-0.mp4"
    assert video.stat().st_size > 1000 and b"ftyp" in video.read_bytes()[:16]


def test_viz_extra_installs_moviepy():
    text = (Path(__file__).resolve().parents[2] / "pyproject.toml").read_text()
    (viz,) = [line for line in text.splitlines() if line.startswith("viz = ")]
    assert '"moviepy' in viz


def test_view_is_fitted_afresh_at_each_reset() -> None:
    """A view widened because the palm left it shrinks back at the next reset: the same seed
    renders the same first frame."""
    import gymnasium as gym

    env = gym.make("FrictionlessGrasp-v0", palm_control=True, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    for _ in range(40):  # drive the palm up and sideways, out of the fitted view
        env.step(np.array([0.0, 0.0, 1.0, 1.0, 0.0], dtype=np.float32))
    assert env.render().shape == first.shape
    env.reset(seed=0)
    np.testing.assert_array_equal(env.render(), first)
    env.close()
