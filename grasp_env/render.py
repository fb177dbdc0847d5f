"""Off-screen pygame rendering of a grasp state, shared by the environment and the planner.

:class:`Renderer` draws a :class:`~grasp_env.core.state.State` onto a ``pygame.Surface`` and returns
it as an ``(H, W, 3)`` uint8 array; nothing here opens a window unless :meth:`Renderer.show`
is called (the ``"human"`` render mode). pygame is imported lazily, inside the functions that
need it, so ``import grasp_env`` never imports it.

Drawing (world frame, y up):

* the support: a grey band below ``y = 0``;
* the palm and the fingers: their world polygons
(:func:`grasp_env.core.kinematics.hand_polygons_W`);
* the object: its vertices in its frame, placed by ``state.object_pose``;
* each contact: a red dot at its point and a green arrow from the point along its normal
  (into the object) of length ``force_scale * force / object weight`` (world units; by
  default a force equal to the object's weight is drawn ``0.25`` palm widths long);
* an optional line of text at the top left, in a band kept clear of the view (``text_band``).

:meth:`Renderer.legend` draws a key to these colours and marks as an image strip.

The world-to-pixel map (x to the right, y up, one scale for both axes) is fixed by
``world_bounds`` if given. Otherwise it is fitted to the first state drawn of a scene: the
hand's workspace with the palm where that state has it (:func:`workspace_bounds`: the palm,
the fingers over most of their range, the object at its scene placement) and the support,
plus a margin, so an episode's video holds still while the fingers move. It is refitted only
when a body leaves the view (the palm moved away, a finger opened wide) or the scene changes.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from grasp_env.view import (
    WorldView,
    _bodies_W,
    scene_bounds,
    workspace_bounds,
)

if TYPE_CHECKING:
    from grasp_env.core.scene import Scene
    from grasp_env.core.state import State

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


class Renderer(WorldView):
    """Off-screen renderer of grasp states.

    Args:
        width: image width in pixels.
        height: image height in pixels.
        world_bounds: ``(x_min, x_max, y_min, y_max)`` of the world to show; the box is grown
            along one axis (about its centre) to keep one scale for x and y.
            None: fitted to the hand's workspace and the object at the first state drawn of a
            scene (:func:`workspace_bounds` with that state's palm pose), refitted only when a
            body leaves the view or the scene changes.
        fps: frame rate of :meth:`show` (the ``"human"`` window).
        font_size: size (pixels) of the text font; None: ``max(14, height // 22)`` (22 for a
            480-pixel frame, whose lines are then about 15 pixels high).
        text_band: keep a band at the top, one line of text high, out of the fitted view, so
            the text never covers a body.
    """

    def __init__(
        self,
        width: int = 640,
        height: int = 480,
        world_bounds: tuple[float, float, float, float] | None = None,
        fps: int = 30,
        font_size: int | None = None,
        text_band: bool = True,
    ) -> None:
        for name, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 16:
                raise ValueError(f"{name} must be an integer >= 16, got {value!r}")
        if font_size is not None and (
            isinstance(font_size, bool) or not isinstance(font_size, int) or font_size < 6
        ):
            raise ValueError(f"font_size must be None or an integer >= 6, got {font_size!r}")
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
        self.font_size = font_size if font_size is not None else max(14, height // 22)
        self.text_band = bool(text_band)
        # what the map was fitted to: the scene of the fitted view, or world_bounds
        self._view_scene: Scene | tuple | None = None
        self._map: tuple[float, float, float] = (0.0, 0.0, 1.0)  # x_min, y_min, px per unit
        self._surface = None
        self._font = None
        self._window = None
        self._clock = None
        self._counted = False

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
            self._font = pygame.font.Font(None, self.font_size)
        return pygame

    @property
    def _dot_radius(self) -> int:
        return max(4, self.height // 80)

    @property
    def _line_width(self) -> int:
        return max(2, self.height // 200)

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
        self._fit(state)
        surf = self._surface
        surf.fill(BACKGROUND)
        top = float(self.to_pixels(np.array([0.0, 0.0]))[1])
        if top < self.height:
            pygame.draw.rect(surf, SUPPORT_COLOR, pygame.Rect(0, top, self.width, self.height))

        def poly(points_W: np.ndarray, fill, outline) -> None:
            pts = [tuple(p) for p in self.to_pixels(points_W)]
            pygame.draw.polygon(surf, fill, pts)
            pygame.draw.polygon(surf, outline, pts, width=1)

        palm, f1, f2, obj_W = _bodies_W(state)
        poly(palm, PALM_COLOR, HAND_OUTLINE)
        poly(f1, FINGER_COLOR, HAND_OUTLINE)
        poly(f2, FINGER_COLOR, HAND_OUTLINE)
        poly(obj_W, OBJECT_COLOR, OBJECT_OUTLINE)

        if force_scale is None:
            force_scale = DEFAULT_FORCE_SCALE * scene.palm.width
        weight = scene.object_weight
        for contact in state.contacts:
            p = self.to_pixels(contact.point)
            length = force_scale * contact.force / weight
            if length > 0:
                tip = self.to_pixels(contact.point + length * contact.normal)
                _arrow(pygame, surf, p, tip, FORCE_COLOR, self._line_width, self.height / 40)
            pygame.draw.circle(surf, CONTACT_COLOR, (float(p[0]), float(p[1])), self._dot_radius)
        if text:
            surf.blit(self._font.render(text, True, TEXT_COLOR, BACKGROUND), (6, 4))
        return np.ascontiguousarray(pygame.surfarray.pixels3d(surf).transpose(1, 0, 2)).copy()

    def legend(
        self, width: int | None = None, force_scale: float = DEFAULT_FORCE_SCALE
    ) -> np.ndarray:
        """A key to the drawing, as an image strip ``(h, width, 3)``: the support, the palm,
        a finger, the object, a contact (red dot) and a contact force (green arrow, a force
        of one object weight ``force_scale`` palm widths long), with the renderer's marks
        and font, in as many rows as ``width`` (default the frame width) needs."""
        pygame = self._ensure()
        width = self.width if width is None else width
        font = self._font
        line = font.get_linesize()
        sw = max(2 * line, 24)  # swatch width
        pad, gap = 8, 2 * line

        def layout(force_label: str) -> list[list]:
            entries = [
                ("support", "band"),
                ("palm", "palm"),
                ("finger", "finger"),
                ("object", "object"),
                ("contact", "dot"),
                (force_label, "arrow"),
            ]
            rows: list[list] = [[]]
            x = pad
            for label, mark in entries:
                img = font.render(label, True, TEXT_COLOR, BACKGROUND)
                w = sw + 6 + img.get_width()
                if rows[-1] and x + w > width - pad:
                    rows.append([])
                    x = pad
                rows[-1].append((x, img, mark))
                x += w + gap
            return rows

        rows = layout(f"contact force (object weight = {force_scale:g} palm widths)")
        short = layout(f"force (object weight = {force_scale:g} palm widths)")
        if len(short) < len(rows):
            rows = short
        row_h = line + 8
        surf = pygame.Surface((width, len(rows) * row_h + pad))
        surf.fill(BACKGROUND)
        fills = {
            "band": (SUPPORT_COLOR, SUPPORT_COLOR),
            "palm": (PALM_COLOR, HAND_OUTLINE),
            "finger": (FINGER_COLOR, HAND_OUTLINE),
            "object": (OBJECT_COLOR, OBJECT_OUTLINE),
        }
        for r, row in enumerate(rows):
            y = pad // 2 + r * row_h
            cy = y + row_h / 2
            for x, img, mark in row:
                if mark in fills:
                    fill, outline = fills[mark]
                    h = line * (0.5 if mark == "finger" else 0.8)
                    rect = pygame.Rect(x, round(cy - h / 2), sw, round(h))
                    pygame.draw.rect(surf, fill, rect)
                    pygame.draw.rect(surf, outline, rect, width=1)
                elif mark == "dot":
                    pygame.draw.circle(surf, CONTACT_COLOR, (x + sw / 2, cy), self._dot_radius)
                else:
                    p0, p1 = np.array([x + 2.0, cy]), np.array([x + sw - 1.0, cy])
                    _arrow(pygame, surf, p0, p1, FORCE_COLOR, self._line_width, self.height / 40)
                    pygame.draw.circle(surf, CONTACT_COLOR, (x + 2.0, cy), self._dot_radius)
                surf.blit(img, (x + sw + 6, round(cy - img.get_height() / 2)))
        return np.ascontiguousarray(pygame.surfarray.pixels3d(surf).transpose(1, 0, 2)).copy()

    def text_image(self, lines: list[str], width: int, bold_first: bool = False) -> np.ndarray:
        """Lines of text on the background, left-aligned, ``(h, width, 3)``: frame titles."""
        pygame = self._ensure()
        font = self._font
        line = font.get_linesize()
        surf = pygame.Surface((width, len(lines) * line + 6))
        surf.fill(BACKGROUND)
        for k, text in enumerate(lines):
            font.set_bold(bold_first and k == 0)
            surf.blit(font.render(text, True, TEXT_COLOR, BACKGROUND), (4, 3 + k * line))
        font.set_bold(False)
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


def _arrow(pygame, surf, p0: np.ndarray, p1: np.ndarray, color, width: int = 1, head=10.0):
    """Arrow from pixel ``p0`` to pixel ``p1`` with a head at ``p1`` (at most ``head`` long)."""
    d = p1 - p0
    n = float(np.hypot(*d))
    pygame.draw.line(surf, color, tuple(p0), tuple(p1), width)
    if n < 1e-9:
        return
    u = d / n
    head = min(max(float(head), 6.0), 0.4 * n)
    side = np.array([-u[1], u[0]])
    a = p1 - head * u + 0.5 * head * side
    b = p1 - head * u - 0.5 * head * side
    pygame.draw.polygon(surf, color, [tuple(p1), tuple(a), tuple(b)])


__all__ = ["DEFAULT_FORCE_SCALE", "Renderer", "scene_bounds", "workspace_bounds"]
