"""Static obstacles of a scenario: discs, boxes and segments, and the one shape the
physical model's contact pass sees, the capsule.

A scenario lists its obstacles in world units, the same in every episode and team
(:class:`~physrover.domain.scenarios.Scenario`):

- discs ``[x, y, radius]`` (:meth:`Scenario.obstacles`);
- boxes ``[x, y, half_width, half_height, angle]``: a rectangle centred at (x, y), its
  width along the direction ``angle`` (radians, counter-clockwise from +x)
  (:meth:`Scenario.boxes`);
- segments ``[ax, ay, bx, by, radius]``: the points within ``radius`` of the segment from
  A to B, a wall of thickness 2 radius with round ends (:meth:`Scenario.segments`).

The physical model makes each a static pymunk shape (circle, polygon, segment) that rovers
collide with, and runs its speculative contact pass against their capsules (a segment A-B
thickened by a radius): a disc is the capsule with A = B, a segment is one, a box is its
four edges with radius 0 (a rover outside a box is nearest one of its edges). The world's
state holds the capsules (``WorldState.obstacles``, (E, M, 5)), for sensors that see them.
"""

from __future__ import annotations

import math

import numpy as np

CAPSULE = 5
"""Numbers per capsule: ``[ax, ay, bx, by, radius]``."""


def box_corners(box) -> np.ndarray:
    """The (4, 2) corners of a box ``[x, y, half_width, half_height, angle]``,
    counter-clockwise (as pymunk's polygons want them)."""
    x, y, hw, hh, angle = (float(v) for v in box)
    c, s = math.cos(angle), math.sin(angle)
    local = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    return np.array([x, y]) + local @ np.array([[c, s], [-s, c]])


def capsules(discs, boxes, segments) -> np.ndarray:
    """(M, 5) capsules of a scenario's discs (n, 3), boxes (n, 5) and segments (n, 5), in
    that order (module docstring)."""
    out = [np.array([x, y, x, y, r], dtype=np.float64) for x, y, r in np.reshape(discs, (-1, 3))]
    for box in np.reshape(boxes, (-1, 5)):
        corners = box_corners(box)
        out += [np.array([*corners[k], *corners[(k + 1) % 4], 0.0]) for k in range(4)]
    out += [np.asarray(seg, dtype=np.float64) for seg in np.reshape(segments, (-1, 5))]
    return np.array(out, dtype=np.float64).reshape(-1, CAPSULE)


def reach(discs, boxes, segments) -> float:
    """The farthest point of any obstacle from the origin (0 without obstacles)."""
    far = [math.hypot(x, y) + r for x, y, r in np.reshape(discs, (-1, 3))]
    far += [float(np.hypot(*box_corners(b).T).max()) for b in np.reshape(boxes, (-1, 5))]
    far += [max(math.hypot(ax, ay), math.hypot(bx, by)) + r
            for ax, ay, bx, by, r in np.reshape(segments, (-1, 5))]  # fmt: skip
    return max(far, default=0.0)


def check_obstacles(discs, boxes, segments, check) -> None:
    """Validate the three lists with ``check(ok, field, message)`` (the config's)."""
    for disc in discs:
        ok = len(disc) == 3 and all(np.isfinite(disc)) and disc[2] > 0
        check(ok, "obstacle_discs", f"every obstacle is [x, y, radius > 0], got {list(disc)}")
    for box in boxes:
        ok = len(box) == 5 and all(np.isfinite(box)) and box[2] > 0 and box[3] > 0
        shape = "[x, y, half_width > 0, half_height > 0, angle]"
        check(ok, "obstacle_boxes", f"every box is {shape}, got {list(box)}")
    for seg in segments:
        ok = len(seg) == 5 and all(np.isfinite(seg)) and seg[4] > 0
        shape = "[ax, ay, bx, by, radius > 0]"
        check(ok, "obstacle_segments", f"every segment is {shape}, got {list(seg)}")
