"""Off-screen pygame rendering of a grasp state, shared by the environment and the planner.

:class:`Renderer` draws a :class:`~grasp_env.state.State` onto a ``pygame.Surface`` and returns
it as an ``(H, W, 3)`` uint8 array; nothing here opens a window unless :meth:`Renderer.show`
is called (the ``"human"`` render mode). pygame is imported lazily, inside the functions that
need it, so ``import grasp_env`` never imports it.

Drawing (world frame, y up):

* the support: a grey band below ``y = 0``;
* the palm and the fingers: their world polygons (:func:`grasp_env.kinematics.hand_polygons_W`);
* the object: its vertices in its frame, placed by ``state.object_pose``;
* each contact: a dot at its point and an arrow from the point along its normal (into the
  object) of length ``force_scale * force / object weight`` (world units; by default a force
  equal to the object's weight is drawn ``0.25`` palm widths long);
* an optional line of text at the top left.

The world-to-pixel map is fixed per scene (:func:`scene_bounds`: the palm's reach and the
object at their scene placement, plus margins) unless ``world_bounds`` is given; x to the
right, y up, one scale for both axes.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from grasp_env import geometry as geo
from grasp_env import kinematics as kin

if TYPE_CHECKING:
    from grasp_env.scene import Scene
    from grasp_env.state import State

#: Length of the arrow of a force equal to the object's weight, in palm widths.
DEFAULT_FORCE_SCALE = 0.25

BACKGROUND = (255, 255, 255)
SUPPORT_COLOR = (170, 170, 170)
PALM_COLOR = (90, 90, 100)
FINGER_COLOR = (120, 120, 135)
HAND_OUTLINE = (40, 40, 40)
OBJECT_COLOR = (70, 130, 200)
OBJECT_OUTLINE = (20, 50, 110)
CONTACT_COLOR = (210, 40, 40)
FORCE_COLOR = (20, 150, 60)
TEXT_COLOR = (0, 0, 0)

# Number of live renderers in this process: pygame is quit when the last one closes, so that
# closing one environment does not break another one's font.
_live_renderers = 0


def _pygame():
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    import pygame

    return pygame


def scene_bounds(scene: Scene, margin: float = 0.15) -> tuple[float, float, float, float]:
    """World box ``(x_min, x_max, y_min, y_max)`` that shows a scene's hand and object.

    It spans the palm's reach at its scene pose (palm plus fingers of any angle) and the
    object at its scene placement, the support band below ``y = 0``, and ``margin`` palm
    widths on every side (twice that above, for lifting).
    """
    w = scene.palm.width
    x_p, y_p, _ = scene.palm.pose
    reach = 0.5 * w + max(f.length + f.thickness for f in scene.fingers)
    obj = scene.object.vertices_W0
    x_min = min(x_p - reach, float(obj[:, 0].min())) - margin * w
    x_max = max(x_p + reach, float(obj[:, 0].max())) + margin * w
    y_min = -margin * w
    y_max = max(y_p + scene.palm.thickness, float(obj[:, 1].max())) + 2.0 * margin * w
    return (x_min, x_max, y_min, y_max)


class Renderer:
    """Off-screen renderer of grasp states.

    Args:
        width: image width in pixels.
        height: image height in pixels.
        world_bounds: ``(x_min, x_max, y_min, y_max)`` of the world to show; the box is grown
            along one axis (centred in x, upwards in y) to keep one scale for x and y.
            None: :func:`scene_bounds` of each state's scene (fixed per scene).
        fps: frame rate of :meth:`show` (the ``"human"`` window).
    """

    def __init__(
        self,
        width: int = 640,
        height: int = 480,
        world_bounds: tuple[float, float, float, float] | None = None,
        fps: int = 30,
    ) -> None:
        for name, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 16:
                raise ValueError(f"{name} must be an integer >= 16, got {value!r}")
        if world_bounds is not None:
            b = np.asarray(world_bounds, dtype=float)
            if b.shape != (4,) or not np.all(np.isfinite(b)) or b[0] >= b[1] or b[2] >= b[3]:
                raise ValueError(
                    "world_bounds must be finite (x_min, x_max, y_min, y_max) with "
                    f"x_min < x_max and y_min < y_max, got {world_bounds!r}"
                )
            world_bounds = tuple(float(x) for x in b)
        self.width, self.height, self.fps = width, height, fps
        self.world_bounds = world_bounds
        self._map_key: object = None
        self._map: tuple[float, float, float] = (0.0, 0.0, 1.0)  # x_min, y_min, px per unit
        self._surface = None
        self._font = None
        self._window = None
        self._clock = None
        self._counted = False

    # ------------------------------------------------------------------ mapping
    def _fit(self, scene: Scene) -> None:
        key = self.world_bounds if self.world_bounds is not None else id(scene)
        if key == self._map_key:
            return
        x0, x1, y0, y1 = self.world_bounds or scene_bounds(scene)
        scale = min(self.width / (x1 - x0), self.height / (y1 - y0))
        # Centre the box horizontally; spare height goes above it (room to lift), so the
        # support band stays thin.
        x0 -= 0.5 * (self.width / scale - (x1 - x0))
        self._map, self._map_key = (x0, y0, scale), key

    def to_pixels(self, p_W: np.ndarray) -> np.ndarray:
        """World points ``(..., 2)`` to pixel coordinates ``(..., 2)`` (y down)."""
        x0, y0, s = self._map
        p = np.asarray(p_W, dtype=float)
        return np.stack([(p[..., 0] - x0) * s, self.height - (p[..., 1] - y0) * s], axis=-1)

    # ------------------------------------------------------------------ drawing
    def _ensure(self):
        global _live_renderers
        pygame = _pygame()
        if not self._counted:
            _live_renderers += 1
            self._counted = True
        if not pygame.font.get_init():
            pygame.font.init()
            self._font = None
        if self._surface is None:
            self._surface = pygame.Surface((self.width, self.height))
        if self._font is None:
            self._font = pygame.font.Font(None, max(12, self.height // 24))
        return pygame

    def draw(self, state: State, text: str = "", force_scale: float | None = None) -> np.ndarray:
        """Draw ``state``; return the image, shape ``(height, width, 3)``, dtype uint8.

        Args:
            state: the state to draw.
            text: one line of text drawn at the top left.
            force_scale: arrow length (world units) of a contact force equal to the object's
                weight; None: ``DEFAULT_FORCE_SCALE`` palm widths.
        """
        pygame = self._ensure()
        scene = state.scene
        self._fit(scene)
        surf = self._surface
        surf.fill(BACKGROUND)
        top = float(self.to_pixels(np.array([0.0, 0.0]))[1])
        if top < self.height:
            pygame.draw.rect(surf, SUPPORT_COLOR, pygame.Rect(0, top, self.width, self.height))

        def poly(points_W: np.ndarray, fill, outline) -> None:
            pts = [tuple(p) for p in self.to_pixels(points_W)]
            pygame.draw.polygon(surf, fill, pts)
            pygame.draw.polygon(surf, outline, pts, width=1)

        palm, f1, f2 = kin.hand_polygons_W(scene, state.hand)
        poly(palm, PALM_COLOR, HAND_OUTLINE)
        poly(f1, FINGER_COLOR, HAND_OUTLINE)
        poly(f2, FINGER_COLOR, HAND_OUTLINE)
        obj_W = geo.transform(state.object_pose, scene.object.vertices_B)
        poly(obj_W, OBJECT_COLOR, OBJECT_OUTLINE)

        if force_scale is None:
            force_scale = DEFAULT_FORCE_SCALE * scene.palm.width
        weight = scene.object_weight
        radius = max(2, self.height // 120)
        for contact in state.contacts:
            p = self.to_pixels(contact.point)
            length = force_scale * contact.force / weight
            if length > 0:
                tip = self.to_pixels(contact.point + length * contact.normal)
                _arrow(pygame, surf, p, tip, FORCE_COLOR, width=max(1, self.height // 240))
            pygame.draw.circle(surf, CONTACT_COLOR, (float(p[0]), float(p[1])), radius)
        if text:
            surf.blit(self._font.render(text, True, TEXT_COLOR), (6, 4))
        return np.ascontiguousarray(pygame.surfarray.pixels3d(surf).transpose(1, 0, 2)).copy()

    # ------------------------------------------------------------------ window
    def show(self, frame: np.ndarray) -> None:
        """Show a frame in a window (opened on first use) and keep to ``fps``."""
        pygame = self._ensure()
        if self._window is None:
            pygame.display.init()
            pygame.display.set_caption("FrictionlessGrasp")
            self._window = pygame.display.set_mode((self.width, self.height))
            self._clock = pygame.time.Clock()
        pygame.event.pump()
        surf = pygame.surfarray.make_surface(np.asarray(frame).transpose(1, 0, 2))
        self._window.blit(surf, (0, 0))
        pygame.display.flip()
        self._clock.tick(self.fps)

    def close(self) -> None:
        """Close the window, if any; quit pygame when no other renderer is live."""
        global _live_renderers
        if not self._counted:
            return
        pygame = _pygame()
        if self._window is not None:
            pygame.display.quit()
        self._window = self._clock = self._surface = self._font = None
        self._counted = False
        _live_renderers -= 1
        if _live_renderers == 0:
            pygame.quit()

    def __getstate__(self) -> dict:
        # pygame objects cannot be pickled; a copy draws afresh.
        d = self.__dict__.copy()
        d.update(_surface=None, _font=None, _window=None, _clock=None, _counted=False)
        return d


def _arrow(pygame, surf, p0: np.ndarray, p1: np.ndarray, color, width: int = 1) -> None:
    """Arrow from pixel ``p0`` to pixel ``p1`` with a head at ``p1``."""
    d = p1 - p0
    n = float(np.hypot(*d))
    pygame.draw.line(surf, color, tuple(p0), tuple(p1), width)
    if n < 1e-9:
        return
    u = d / n
    head = min(10.0, 0.4 * n)
    side = np.array([-u[1], u[0]])
    a = p1 - head * u + 0.5 * head * side
    b = p1 - head * u - 0.5 * head * side
    pygame.draw.polygon(surf, color, [tuple(p1), tuple(a), tuple(b)])


__all__ = ["DEFAULT_FORCE_SCALE", "Renderer", "scene_bounds"]
