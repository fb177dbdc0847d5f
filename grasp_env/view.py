"""What a rendered frame shows: the world box of a scene's view (:func:`workspace_bounds`,
:func:`scene_bounds`) and the world-to-pixel map fitted to it (:class:`WorldView`).

Kept apart from the drawing with pygame (:mod:`grasp_env.render`, whose ``Renderer`` is a
:class:`WorldView`; how the view is fitted and refitted is in that module's docstring), so
that the geometry of the view needs no pygame.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin

if TYPE_CHECKING:
    from grasp_env.core.scene import Scene
    from grasp_env.core.state import State

__all__ = ["VIEW_MARGIN", "VIEW_OPENING", "WorldView", "scene_bounds", "workspace_bounds"]

#: Margin around the fitted view, in palm widths.
VIEW_MARGIN = 0.1
#: How far (rad) the view covers the fingers opening past pointing straight down from the
#: palm (all of their closing range is covered).
VIEW_OPENING = 0.5


def workspace_bounds(
    scene: Scene, palm_pose: np.ndarray | None = None, margin: float = VIEW_MARGIN
) -> tuple[float, float, float, float]:
    """World box ``(x_min, x_max, y_min, y_max)`` of the hand's workspace and the object.

    It spans the palm at ``palm_pose`` (default: the scene's), each finger swept over its
    whole closing range and opened up to ``VIEW_OPENING`` rad past pointing straight down
    from the palm, the object at its scene placement, the support up to ``y = 0``, and
    ``margin`` palm widths on every side (the support band below ``y = 0`` is that margin).
    """
    w = scene.palm.width
    palm = scene.palm.pose if palm_pose is None else np.asarray(palm_pose, dtype=float)[:3]
    down = -0.5 * math.pi
    (lo1, hi1), (lo2, hi2) = scene.joint_limits
    # finger 1 closes as q1 grows, finger 2 as q2 falls
    q1 = np.linspace(max(lo1, min(down - VIEW_OPENING, hi1)), hi1, 25)
    q2 = np.linspace(lo2, min(hi2, max(down + VIEW_OPENING, lo2)), 25)
    pts = [scene.object.vertices_W0]
    for a, b in zip(q1, q2, strict=True):
        pts.extend(kin.hand_polygons_W(scene, np.array([*palm, a, b])))
    p = np.vstack(pts)
    m = margin * w
    y_min = min(0.0, float(p[:, 1].min())) - m
    return (float(p[:, 0].min()) - m, float(p[:, 0].max()) + m, y_min, float(p[:, 1].max()) + m)


def scene_bounds(scene: Scene, margin: float = VIEW_MARGIN) -> tuple[float, float, float, float]:
    """:func:`workspace_bounds` with the palm at its scene pose: the view of a scene's start."""
    return workspace_bounds(scene, None, margin)


def _bodies_W(state: State) -> list[np.ndarray]:
    """World polygons of the palm, the fingers and the object."""
    scene = state.scene
    obj = geo.transform(state.object_pose, scene.object.vertices_B)
    return [*kin.hand_polygons_W(scene, state.hand), obj]


class WorldView:
    """The world-to-pixel map of frames ``width`` x ``height`` pixels large (x to the right,
    y up, one scale for both axes), fixed by ``world_bounds`` or fitted to the state drawn.

    The attributes ``width``, ``height``, ``world_bounds``, ``font_size``, ``text_band``,
    ``_view_scene`` and ``_map`` are set by the subclass (:class:`~grasp_env.render.Renderer`).
    """

    width: int
    height: int
    world_bounds: tuple[float, float, float, float] | None
    font_size: int
    text_band: bool
    _view_scene: Scene | tuple | None
    _map: tuple[float, float, float]

    @property
    def band(self) -> int:
        """Height in pixels of the text band at the top (0 without ``text_band``)."""
        return min(round(0.8 * self.font_size) + 8, self.height // 3) if self.text_band else 0

    def reset_view(self) -> None:
        """Fit the view afresh at the next frame (a new episode: a view widened because a body
        left it in the last one shrinks back)."""
        self._view_scene = None

    def _fit(self, state: State) -> None:
        """Fix the world-to-pixel map for ``state`` (see the class docstring)."""
        if self.world_bounds is not None:
            if self._view_scene != self.world_bounds:
                self._set_map(self.world_bounds)
                self._view_scene = self.world_bounds
            return
        scene = state.scene
        if self._view_scene is scene and self._shows(state):
            return
        box = np.array(workspace_bounds(scene, state.hand[:3]))
        if self._view_scene is scene:  # a body left the view: take it in
            p = np.vstack(_bodies_W(state))
            m = VIEW_MARGIN * scene.palm.width
            box = np.r_[
                min(box[0], p[:, 0].min() - m),
                max(box[1], p[:, 0].max() + m),
                min(box[2], p[:, 1].min() - m),
                max(box[3], p[:, 1].max() + m),
            ]
        self._set_map(tuple(float(x) for x in box))
        self._view_scene = scene

    def _set_map(self, box: tuple[float, float, float, float]) -> None:
        x0, x1, y0, y1 = box
        room = self.height - self.band
        scale = min(self.width / (x1 - x0), room / (y1 - y0))
        # Centre the box in the room below the text band.
        x0 -= 0.5 * (self.width / scale - (x1 - x0))
        y0 -= 0.5 * (room / scale - (y1 - y0))
        self._map = (x0, y0, scale)

    def view(self) -> tuple[float, float, float, float]:
        """World box ``(x_min, x_max, y_min, y_max)`` shown below the text band."""
        x0, y0, s = self._map
        return (x0, x0 + self.width / s, y0, y0 + (self.height - self.band) / s)

    def _shows(self, state: State) -> bool:
        """Every body of ``state`` lies within the view."""
        x0, x1, y0, y1 = self.view()
        p = np.vstack(_bodies_W(state))
        lo, hi = p.min(axis=0), p.max(axis=0)
        return bool(lo[0] >= x0 and hi[0] <= x1 and lo[1] >= y0 and hi[1] <= y1)

    def to_pixels(self, p_W: np.ndarray) -> np.ndarray:
        """World points ``(..., 2)`` to pixel coordinates ``(..., 2)`` (y down)."""
        x0, y0, s = self._map
        p = np.asarray(p_W, dtype=float)
        return np.stack([(p[..., 0] - x0) * s, self.height - (p[..., 1] - y0) * s], axis=-1)
