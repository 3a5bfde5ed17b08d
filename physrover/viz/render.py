"""Off-screen frames of an episode, drawn with OpenCV (no display, no GL).

A frame shows one team:

- POIs as circles sized by value, with their capture-radius ring, grey until captured and
  green from the step of capture, labelled with their value (above right) and ``n/n_req``
  (under the ring): the rovers within ``d_cap`` of the POI now (as the world's scoring counted
  them, ``RoverWorld.poi_counts``) against the coupling, green when it is met now; once
  captured, ``captured tN`` in green, each label off the rovers (:mod:`physrover.viz.labels`).
- Each rover as a filled circle in its own colour (consistent by index; no greys or greens,
  so a rover never looks like a POI) with a thin dark outline, so overlapping bodies stay
  distinct, a heading tick and a trail of its last positions.
- While the team is a tight clump (the spawn disc at the first steps), a zoomed inset of it
  at the top right, its area marked by a grey rectangle in the main view.
- A crowd (more rovers than the palette's :data:`CROWD` colours, which could no longer
  tell them apart) is drawn as a crowd: each rover a dot of one colour at its true size (at
  least a pixel), without trails, ticks or inset, and the POIs drawn again on top, so a
  thousand rovers stay a legible density around visible POIs.
- A HUD with the step, G, n_req and the motion model (and, for physics, collisions on/off),
  and a one-line legend of the POI labels, in a band at the top that the view keeps clear
  (:data:`HUD_PX`; the bottom band, :data:`FOOTER_PX`, is a panel's label).

World-to-pixel transform (:class:`Transform`): one scale for x and y (equal aspect), world
y up on screen, fitted to a box holding every POI with its capture ring and every rover
position given, plus ``margin`` world units. :func:`draw_frame` fits the trajectory so far
(so ``RoverEnv.render()`` and each panel of :mod:`physrover.experiment.playback`'s videos
frame what is on screen now, zooming out as the team spreads and never back in, never
cutting a rover).

Frame sizes are even (:class:`RenderConfig` requires it): :mod:`physrover.viz.video` writes the
frames as H.264 yuv420p MP4 (no hidden padding: a frame is the video's size). Its
:class:`VideoWriter` and :class:`VideoError` are importable from here too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import cv2
import numpy as np

from physrover.config import ConfigBase, DomainConfig, check
from physrover.config.domain import extent_of
from physrover.domain.obstacles import box_corners
from physrover.viz import classes as marks
from physrover.viz.labels import (
    BACKGROUND,
    POI_CAPTURED,
    TEXT,
    label_at,
    label_box,
    poi_status,
    text_at,
)
from physrover.viz.video import VideoError, VideoWriter

POI_FREE = (150, 150, 150)  # BGR
OUTLINE = (30, 30, 30)  # rover body outlines
OBSTACLE = (110, 110, 110)  # the scenario's static discs
# Rover colours, cycled by index, as RGB: 20 hues picked greedily, each as far as it can
# be (CIE76 colour difference >= 30) from the others, the background and the POI colours,
# never grey or green (the POI colours); tests/test_pictures.py checks it.
PALETTE_RGB = [
    (31, 119, 180), (214, 39, 40), (0, 0, 255), (217, 0, 173), (255, 204, 0),
    (0, 0, 115), (115, 92, 0), (0, 255, 255), (115, 0, 69), (157, 115, 255),
    (255, 115, 157), (255, 171, 115), (204, 0, 255), (255, 128, 0), (115, 41, 23),
    (115, 213, 255), (71, 52, 115), (166, 166, 33), (0, 115, 115), (0, 76, 255),
]  # fmt: skip
PALETTE = [c[::-1] for c in PALETTE_RGB]  # BGR, as OpenCV draws
CROWD = len(PALETTE)
"""Teams of more rovers than this are drawn as a crowd (module docstring)."""
CROWD_COLOUR = (120, 70, 40)  # BGR: a crowd's rovers (dark blue, apart from POI greys/greens)
ROVER_PX = 6
"""Smallest drawn rover radius, pixels (the body's true size when larger)."""
ID_SCALE = 0.5
"""Font scale of the rovers' indices (``RenderConfig.ids``)."""

HUD_PX = 66
"""Pixels at the top of a frame kept for the HUD (three lines): the view never puts a POI
or a rover there."""
FOOTER_PX = 26
"""Pixels at the bottom kept for a panel's label (:func:`label`)."""

INSET_ZOOM = 2.0
"""Smallest zoom at which the clump inset is drawn (see ``_draw_clump_inset``)."""
INSET_GAP = 8
"""Pixels between the inset and the frame's top-right corner."""


def rover_colour(index: int) -> tuple[int, int, int]:
    """BGR colour of rover ``index`` (as OpenCV draws it)."""
    return PALETTE[index % len(PALETTE)]


def rover_rgb(index: int) -> tuple[int, int, int]:
    """RGB colour of rover ``index`` in the frames this module returns."""
    return PALETTE_RGB[index % len(PALETTE_RGB)]


@dataclass(frozen=True)
class RenderConfig(ConfigBase):
    """Frame and video settings."""

    section: ClassVar[str] = "render"

    width: int = 640
    """Frame width, pixels (even: H.264 yuv420p)."""
    height: int = 640
    """Frame height, pixels (even: H.264 yuv420p)."""
    fps: int = 10
    """Video frames per second (one frame per environment step)."""
    trail: int = 12
    """Steps of trail drawn behind each rover."""
    margin: float = 2.0
    """World units shown beyond the POIs' capture rings and the rovers' positions."""
    ids: bool = False
    """Draw each rover's index beside it (``physrover render --ids``)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        for name in ("width", "height"):
            value = getattr(self, name)
            check(16 <= value <= 8192, name, f"out of range [16, 8192], got {value}")
            check(value % 2 == 0, name, f"must be even (H.264 yuv420p video), got {value}")
        check(1 <= self.fps <= 240, "fps", f"out of range [1, 240], got {self.fps}")
        check(self.trail >= 0, "trail", f"must be >= 0, got {self.trail}")
        check(self.margin >= 0, "margin", f"must be >= 0, got {self.margin}")


@dataclass(frozen=True)
class Transform:
    """World (x, y) -> pixel (column, row): ``px = cx + s x``, ``py = cy - s y``."""

    scale: float
    cx: float
    cy: float

    @classmethod
    def fit(
        cls,
        domain: DomainConfig,
        render: RenderConfig,
        poi_positions: np.ndarray | None = None,
        rover_positions: np.ndarray | None = None,
    ) -> Transform:
        """The view of a box holding every POI with its capture ring, every rover position
        and ``render.margin`` world units around them, centred in the frame, with one scale
        (pixels per world unit) for x and y, and ``ROVER_PX + 1`` pixels to spare at the edges.

        Args:
            poi_positions: (..., 2) world positions; default: the square around the scenario's
                extent (the view of the start state).
            rover_positions: (..., 2) world positions, any leading shape (e.g. the
                (T + 1, R, 2) positions of a whole episode); default: none.
        """
        if poi_positions is None:
            half = extent_of(domain.scenario, domain.n_rovers) + domain.d_cap
            lo, hi = np.full(2, -half), np.full(2, half)
        else:
            pois = np.asarray(poi_positions, dtype=np.float64).reshape(-1, 2)
            lo, hi = pois.min(0) - domain.d_cap, pois.max(0) + domain.d_cap
        if rover_positions is not None:
            rovers = np.asarray(rover_positions, dtype=np.float64).reshape(-1, 2)
            rovers = rovers[np.isfinite(rovers).all(1)]
            if len(rovers):
                lo, hi = np.minimum(lo, rovers.min(0)), np.maximum(hi, rovers.max(0))
        lo, hi = lo - render.margin, hi + render.margin
        pad = ROVER_PX + 1
        top, bottom = HUD_PX, FOOTER_PX  # the HUD's and the label's bands stay clear
        scale = min((render.width - 2 * pad) / (hi[0] - lo[0]),
                    (render.height - top - bottom - 2 * pad) / (hi[1] - lo[1]))  # fmt: skip
        centre = (lo + hi) / 2.0
        return cls(
            float(scale),
            render.width / 2.0 - scale * centre[0],
            top + (render.height - top - bottom) / 2.0 + scale * centre[1],
        )

    @classmethod
    def fit_states(
        cls, states: list[FrameState], domain: DomainConfig, render: RenderConfig
    ) -> Transform:
        """One view holding the POIs and every rover position of all ``states``."""
        return cls.fit(
            domain,
            render,
            np.concatenate([s.poi_positions.reshape(-1, 2) for s in states]),
            np.concatenate([s.positions.reshape(-1, 2) for s in states]),
        )

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64)
        return np.stack([self.cx + self.scale * xy[..., 0], self.cy - self.scale * xy[..., 1]], -1)


@dataclass(frozen=True)
class FrameState:
    """What one frame shows (one team).

    Attributes:
        positions: (t + 1, R, 2) rover world positions from reset to now (the last row is
            now).
        headings: (R,) current headings, radians counter-clockwise from the world x axis.
        poi_positions: (K, 2) world positions; poi_values: (K,).
        capture_step: (K,) step at which each POI was first captured, -1 if not yet.
        poi_counts: (K,) rovers within d_cap of each POI now (Eq. 13, the world's count).
        step: current step t; G: score so far.
        alive: (R,) bool, the agents that have not failed (``[failures]``); None: all.
    """

    positions: np.ndarray
    headings: np.ndarray
    poi_positions: np.ndarray
    poi_values: np.ndarray
    capture_step: np.ndarray
    poi_counts: np.ndarray
    step: int
    G: float
    alive: np.ndarray | None = None


def _pt(p) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def _draw_rovers(img, tf: Transform, positions, headings, domain: DomainConfig,
                 ids: bool = False) -> None:  # fmt: skip
    """Draw (n, R, 2) world positions as trails ending in outlined bodies with heading ticks
    (later indices on top); bodies at their true size, at least ``ROVER_PX`` pixels;
    ``ids``: each rover's index beside its body. A crowd (more than :data:`CROWD` rovers):
    dots at their true size, at least a pixel, nothing else."""
    aa = cv2.LINE_AA
    radii = domain.physics.per_rover("rover_radius", positions.shape[1])  # to scale, per rover
    trail = tf(positions)  # (n, R, 2) pixels
    now = trail[-1]
    if now.shape[0] > CROWD:
        for i in range(now.shape[0]):
            radius_px = max(1, int(round(tf.scale * radii[i])))
            cv2.circle(img, _pt(now[i]), radius_px, CROWD_COLOUR, -1, aa)
        return
    if len(trail) > 1:
        for i in range(now.shape[0]):
            pts = np.round(trail[:, i]).astype(np.int32).reshape(-1, 1, 2)
            cv2.polylines(img, [pts], False, rover_colour(i), 1, aa)
    for i in range(now.shape[0]):
        radius_px = max(ROVER_PX, int(round(tf.scale * radii[i])))
        cv2.circle(img, _pt(now[i]), radius_px, rover_colour(i), -1, aa)
        cv2.circle(img, _pt(now[i]), radius_px, OUTLINE, 1, aa)
        # Heading tick from the body's edge outwards, so the body keeps its colour.
        direction = np.array([np.cos(headings[i]), -np.sin(headings[i])])
        cv2.line(img, _pt(now[i] + radius_px * direction),
                 _pt(now[i] + 2.2 * radius_px * direction), TEXT, 2, aa)  # fmt: skip
    if ids:  # dark on a light rim: legible over any body or trail colour
        for i in range(now.shape[0]):
            radius_px = max(ROVER_PX, int(round(tf.scale * radii[i])))
            corner = (int(now[i][0]) + radius_px + 1, int(now[i][1]) - radius_px - 1)
            text_at(img, str(i), corner, ID_SCALE, TEXT, 1, halo=True)


def _draw_pois(img, tf: Transform, state, domain: DomainConfig) -> list:
    """The POIs: capture ring and a disc sized by value, grey, green once captured; returns
    their pixel centres."""
    aa = cv2.LINE_AA
    vmax = float(np.max(state.poi_values))
    centres = [_pt(p) for p in tf(state.poi_positions)]
    for k, value in enumerate(state.poi_values):
        captured = 0 <= state.capture_step[k] <= state.step
        colour = POI_CAPTURED if captured else POI_FREE
        cv2.circle(img, centres[k], marks.ring_pixels(tf, domain, k), colour, 1, aa)
        cv2.circle(img, centres[k], int(4 + 8 * value / vmax), colour, -1, aa)
    return centres


def _draw_clump_inset(img, now, headings, tf: Transform, domain: DomainConfig) -> None:
    """While the team is a clump, zoom into it in an inset at the top right.

    The inset (a quarter of the frame's shorter side, square) shows the bounding box of the
    (R, 2) rovers ``now`` plus 0.5 world units, marked by a grey rectangle in the main view,
    when that zooms in at least ``INSET_ZOOM`` times: the spawn disc at the first steps (x2.3
    at the default sizes), and any later equally tight clump."""
    now = now[np.isfinite(now).all(1)]
    size = min(img.shape[:2]) // 4
    if len(now) < 2 or len(now) > CROWD:  # a crowd's inset would be as crowded
        return
    lo, hi = now.min(0) - 0.5, now.max(0) + 0.5
    scale = (size - 6 * ROVER_PX) / float(np.max(hi - lo))  # room for bodies and ticks
    if scale < INSET_ZOOM * tf.scale:
        return
    cv2.rectangle(img, _pt(tf(lo)), _pt(tf(hi)), POI_FREE, 1)
    centre = (lo + hi) / 2.0
    zoom = Transform(scale, size / 2.0 - scale * centre[0], size / 2.0 + scale * centre[1])
    canvas = np.empty((size, size, 3), dtype=np.uint8)
    canvas[:] = BACKGROUND
    _draw_rovers(canvas, zoom, now[None], headings, domain)
    cv2.rectangle(canvas, (0, 0), (size - 1, size - 1), TEXT, 1)
    text_at(canvas, f"x{scale / tf.scale:.1f}", (5, size - 6), 0.4, TEXT)
    x0 = img.shape[1] - size - INSET_GAP
    img[INSET_GAP : INSET_GAP + size, x0 : x0 + size] = canvas


def _draw_obstacles(img: np.ndarray, tf: Transform, scenario) -> None:
    """The scenario's static discs, boxes and segments, filled, to scale."""
    aa = cv2.LINE_AA
    for x, y, r in scenario.obstacles():
        centre = _pt(tf(np.array([[x, y]]))[0])
        cv2.circle(img, centre, max(1, int(round(tf.scale * r))), OBSTACLE, -1, aa)
    for box in scenario.boxes():
        corners = np.round(tf(box_corners(box))).astype(np.int32)
        cv2.fillPoly(img, [corners], OBSTACLE, aa)
    for ax, ay, bx, by, r in scenario.segments():
        a, b = (_pt(p) for p in tf(np.array([[ax, ay], [bx, by]])))
        cv2.line(img, a, b, OBSTACLE, max(1, int(round(2.0 * tf.scale * r))), aa)
        for end in (a, b):  # round ends
            cv2.circle(img, end, max(1, int(round(tf.scale * r))), OBSTACLE, -1, aa)


def draw_frame(
    state: FrameState,
    domain: DomainConfig,
    render: RenderConfig,
    transform: Transform | None = None,
) -> np.ndarray:
    """One (H, W, 3) uint8 RGB frame of ``state``, in ``transform``'s view (default: the
    POIs and the trajectory so far, :meth:`Transform.fit_states`)."""
    tf = transform or Transform.fit_states([state], domain, render)
    img = np.empty((render.height, render.width, 3), dtype=np.uint8)
    img[:] = BACKGROUND
    _draw_obstacles(img, tf, domain.scenario)  # under everything else
    # POIs (rings, discs by value); the rovers' trails and bodies; a crowd's POIs on top.
    centres = _draw_pois(img, tf, state, domain)
    _draw_rovers(img, tf, state.positions[-(render.trail + 1) :], state.headings, domain,
                 render.ids)  # fmt: skip
    marks.mark_classes(img, tf, state.positions[-1], domain, ROVER_PX, rover_colour)
    marks.mark_failed(img, tf, state.positions[-1], state.alive, ROVER_PX)
    if state.positions.shape[1] > CROWD:
        _draw_pois(img, tf, state, domain)
    # POI labels on top of the rovers, each where it covers the fewest rovers: the value
    # (and rules), and the rovers in range / n_req or, once captured, when.
    bodies = [label_box(_pt(p), ROVER_PX) for p in tf(state.positions[-1])]
    placed: list = []
    for k, ((x, y), value) in enumerate(zip(centres, state.poi_values, strict=True)):
        ring = marks.ring_pixels(tf, domain, k)
        text = f"{value:g} {marks.poi_rule_label(domain, k)}".strip()
        spots = [(x + 12, y - 10, "left"), (x - 12, y - 10, "right"), (x + 12, y + 20, "left"),
                 (x - 12, y + 20, "right")]  # fmt: skip
        label_at(img, text, spots, 0.45, TEXT, 1, bodies + placed, placed)
        text, colour, thickness = poi_status(state, domain, k)
        spots = [(x, y + ring + 17, "centre"), (x, y - ring - 6, "centre"),
                 (x + ring + 6, y + 5, "left"), (x - ring - 6, y + 5, "right")]  # fmt: skip
        label_at(img, text, spots, 0.5, colour, thickness, bodies + placed, placed)
    _draw_clump_inset(img, state.positions[-1], state.headings, tf, domain)
    # HUD.
    collisions = f" (collisions {'on' if domain.physics.collisions else 'off'})"
    motion = domain.motion + (collisions if domain.motion == "physics" else "")
    lines = [(f"step {state.step}/{domain.steps}   G {state.G:g}", 0.55),
             (f"n_req {domain.n_req}   {motion}", 0.55), *marks.class_legend(domain),
             *marks.failure_legend(state.alive)]  # fmt: skip
    for j, (text, size) in enumerate(lines):
        text_at(img, text, (10, 20 + 20 * j), size, TEXT)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def world_state(world, team: int) -> FrameState:
    """A copy of what team ``team`` of a :class:`~physrover.domain.world.RoverWorld` shows
    now (the world reuses its arrays, so a kept state must not be a view)."""
    t = world.t
    return FrameState(
        positions=world.position_history[: t + 1, team].copy(),
        headings=np.array(world.rover_headings[team]),
        poi_positions=np.array(world.poi_positions[team]),
        poi_values=np.array(world.poi_values[team]),
        capture_step=np.array(world.state.capture_step[team]),
        poi_counts=np.array(world.poi_counts[team]),
        step=t,
        G=float(world.G[team]),
        alive=world.alive[team] if world.plan.step.failures is not None else None,
    )


def world_frame(world, team: int, render: RenderConfig) -> np.ndarray:
    """The frame of team ``team`` of a :class:`~physrover.domain.world.RoverWorld` now, in the
    view of its POIs and its trajectory so far."""
    return draw_frame(world_state(world, team), world.config, render)


def label(frame: np.ndarray, text: str) -> np.ndarray:
    """A copy of an RGB frame with ``text`` in its bottom-left corner."""
    out = frame.copy()
    text_at(out, text, (10, out.shape[0] - 12), 0.6, TEXT[::-1])
    return out


__all__ = ["FrameState", "RenderConfig", "Transform", "VideoError", "VideoWriter", "draw_frame",
           "label", "rover_colour", "rover_rgb", "world_frame", "world_state"]  # fmt: skip
