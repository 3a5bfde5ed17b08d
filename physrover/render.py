"""Off-screen episode rendering with OpenCV (no display, no GL) and checked MP4 writing.

A frame shows one team: POIs as circles sized by value, with their capture-radius ring,
grey until captured and green from the step of capture; each rover as a filled circle in
its own colour (consistent by index) with a heading tick and a trail of its last positions;
a HUD with the step, G, n_req and the motion model (and, for physics, collisions on/off).

World-to-pixel transform: the view is centred on the origin and fits the POI ring plus the
capture radius plus a margin; world y points up on screen.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np

from physrover.config import ConfigBase, DomainConfig, check

BACKGROUND = (246, 246, 246)  # BGR
POI_FREE = (150, 150, 150)
POI_CAPTURED = (60, 170, 60)
TEXT = (40, 40, 40)
# Rover colours (BGR), cycled by index: a colour-blind-friendly qualitative palette.
PALETTE = [
    (180, 119, 31), (14, 127, 255), (44, 160, 44), (40, 39, 214), (189, 103, 148),
    (75, 86, 140), (194, 119, 227), (34, 189, 188), (207, 190, 23), (127, 127, 127),
    (232, 199, 174), (120, 187, 255), (138, 223, 152), (150, 152, 255), (213, 176, 197),
]  # fmt: skip


def rover_colour(index: int) -> tuple[int, int, int]:
    """BGR colour of rover ``index`` (as OpenCV draws it)."""
    return PALETTE[index % len(PALETTE)]


def rover_rgb(index: int) -> tuple[int, int, int]:
    """RGB colour of rover ``index`` in the frames this module returns."""
    return rover_colour(index)[::-1]


@dataclass(frozen=True)
class RenderConfig(ConfigBase):
    """Frame and video settings."""

    section: ClassVar[str] = "render"

    width: int = 640
    """Frame width, pixels."""
    height: int = 640
    """Frame height, pixels."""
    fps: int = 10
    """Video frames per second (one frame per environment step)."""
    trail: int = 12
    """Steps of trail drawn behind each rover."""
    margin: float = 2.0
    """World units shown beyond the POI ring plus capture radius."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        for name in ("width", "height", "fps"):
            value = getattr(self, name)
            check(
                16 <= value <= 8192 if name != "fps" else 1 <= value <= 240,
                name,
                f"out of range, got {value}",
            )
        check(self.trail >= 0, "trail", f"must be >= 0, got {self.trail}")
        check(self.margin >= 0, "margin", f"must be >= 0, got {self.margin}")


@dataclass(frozen=True)
class Transform:
    """World (x, y) -> pixel (column, row): ``px = cx + s x``, ``py = cy - s y``."""

    scale: float
    cx: float
    cy: float

    @classmethod
    def fit(cls, domain: DomainConfig, render: RenderConfig) -> Transform:
        half = domain.poi_ring_radius + domain.d_cap + render.margin
        scale = min(render.width, render.height) / (2.0 * half)
        return cls(scale, render.width / 2.0, render.height / 2.0)

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64)
        return np.stack([self.cx + self.scale * xy[..., 0], self.cy - self.scale * xy[..., 1]], -1)


@dataclass(frozen=True)
class FrameState:
    """What one frame shows (one team).

    Attributes:
        positions: (t + 1, R, 2) rover positions from reset to now (the last row is now).
        headings: (R,) current headings, radians.
        poi_positions: (K, 2); poi_values: (K,).
        capture_step: (K,) step at which each POI was first captured, -1 if not yet.
        step: current step t; G: score so far.
    """

    positions: np.ndarray
    headings: np.ndarray
    poi_positions: np.ndarray
    poi_values: np.ndarray
    capture_step: np.ndarray
    step: int
    G: float


def _pt(p) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def draw_frame(state: FrameState, domain: DomainConfig, render: RenderConfig) -> np.ndarray:
    """One (H, W, 3) uint8 RGB frame of ``state``."""
    tf = Transform.fit(domain, render)
    img = np.empty((render.height, render.width, 3), dtype=np.uint8)
    img[:] = BACKGROUND
    aa = cv2.LINE_AA
    # POIs: capture ring, then a disc sized by value.
    vmax = float(np.max(state.poi_values))
    for k, (pos, value) in enumerate(zip(state.poi_positions, state.poi_values, strict=True)):
        captured = 0 <= state.capture_step[k] <= state.step
        colour = POI_CAPTURED if captured else POI_FREE
        centre = _pt(tf(pos))
        cv2.circle(img, centre, max(1, int(tf.scale * domain.d_cap)), colour, 1, aa)
        cv2.circle(img, centre, int(4 + 8 * value / vmax), colour, -1, aa)
        cv2.putText(img, f"{value:g}", (centre[0] + 12, centre[1] - 10),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.45, TEXT, 1, aa)  # fmt: skip
    # Rovers: trail, body, heading tick.
    radius_px = max(6, int(round(tf.scale * domain.rover_radius)))
    trail = tf(state.positions[-(render.trail + 1) :])  # (n, R, 2)
    now = trail[-1]
    for i in range(now.shape[0]):
        colour = rover_colour(i)
        if len(trail) > 1:
            pts = np.round(trail[:, i]).astype(np.int32).reshape(-1, 1, 2)
            cv2.polylines(img, [pts], False, colour, 1, aa)
        cv2.circle(img, _pt(now[i]), radius_px, colour, -1, aa)
        # Heading tick from the body's edge outwards, so the body keeps its colour.
        direction = np.array([np.cos(state.headings[i]), -np.sin(state.headings[i])])
        cv2.line(img, _pt(now[i] + radius_px * direction),
                 _pt(now[i] + 2.2 * radius_px * direction), TEXT, 2, aa)  # fmt: skip
    # HUD.
    motion = domain.motion
    if motion == "physics":
        motion += f" (collisions {'on' if domain.collisions else 'off'})"
    lines = [
        f"step {state.step}/{domain.steps}   G {state.G:g}",
        f"n_req {domain.n_req}   {motion}",
    ]
    for j, text in enumerate(lines):
        cv2.putText(img, text, (10, 22 + 20 * j), cv2.FONT_HERSHEY_SIMPLEX, 0.55, TEXT, 1, aa)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def world_frame(world, team: int, render: RenderConfig) -> np.ndarray:
    """The frame of team ``team`` of a :class:`~physrover.domain.world.RoverWorld` now."""
    t = world.t
    state = FrameState(
        positions=world.position_history[: t + 1, team],
        headings=world.rover_headings[team],
        poi_positions=world.poi_positions[team],
        poi_values=world.poi_values[team],
        capture_step=world.scores.capture_step[team],
        step=t,
        G=float(world.G[team]),
    )
    return draw_frame(state, world.config, render)


class VideoError(RuntimeError):
    """The video could not be written completely."""


class VideoWriter:
    """MP4 (``mp4v``) writer that fails loudly instead of leaving an empty or short file.

    The PyPI OpenCV wheels cannot write H.264, hence ``mp4v``. Frames are RGB uint8 of the
    configured size; anything else raises before it reaches OpenCV (which would silently
    drop it). On close the file is read back and its frame count checked.
    """

    def __init__(self, path: str | Path, width: int, height: int, fps: int):
        self.path = Path(path)
        self.size = (width, height)
        if not self.path.parent.is_dir():
            raise VideoError(f"cannot write {self.path}: no directory {self.path.parent}")
        self._writer = cv2.VideoWriter(
            str(self.path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), self.size
        )
        if not self._writer.isOpened():
            raise VideoError(f"cannot open {self.path} for writing (mp4v)")
        self.frames = 0

    def write(self, frame: np.ndarray) -> None:
        expected = (self.size[1], self.size[0], 3)
        if frame.shape != expected or frame.dtype != np.uint8:
            self.close(check=False)
            raise VideoError(
                f"frame must be uint8 of shape {expected}, got {frame.dtype} {frame.shape}"
            )
        ok = self._writer.write(np.ascontiguousarray(frame[..., ::-1]))  # RGB -> BGR
        if ok is False:  # OpenCV >= 5 reports failures; older versions return None
            self.close(check=False)
            raise VideoError(f"writing frame {self.frames} of {self.path} failed")
        self.frames += 1

    def close(self, check: bool = True) -> None:
        if self._writer is None:
            return
        self._writer.release()
        self._writer = None
        if not check:
            return
        capture = cv2.VideoCapture(str(self.path))
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) if capture.isOpened() else 0
        capture.release()
        if count != self.frames:
            raise VideoError(f"{self.path} holds {count} frames, {self.frames} were written")

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(check=exc_type is None)


def label(frame: np.ndarray, text: str) -> np.ndarray:
    """A copy of an RGB frame with ``text`` in its bottom-left corner."""
    out = frame.copy()
    cv2.putText(out, text, (10, out.shape[0] - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                TEXT[::-1], 1, cv2.LINE_AA)  # fmt: skip
    return out


__all__ = [
    "FrameState",
    "RenderConfig",
    "Transform",
    "VideoError",
    "VideoWriter",
    "draw_frame",
    "label",
    "rover_colour",
    "rover_rgb",
    "world_frame",
]
