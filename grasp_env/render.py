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

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from grasp_env.core import geometry as geo
from grasp_env.core import kinematics as kin

if TYPE_CHECKING:
    from grasp_env.core.scene import Scene
    from grasp_env.core.state import State

#: Length of the arrow of a force equal to the object's weight, in palm widths.
DEFAULT_FORCE_SCALE = 0.25
#: Margin around the fitted view, in palm widths.
VIEW_MARGIN = 0.1
#: How far (rad) the view covers the fingers opening past pointing straight down from the
#: palm (all of their closing range is covered).
VIEW_OPENING = 0.5

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


class Renderer:
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

    # ------------------------------------------------------------------ mapping
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
