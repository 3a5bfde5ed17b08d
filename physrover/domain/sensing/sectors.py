"""Which sector of bearing an object lies in: the one convention every sensor uses.

Quadrant convention (the one of the paper's lab's rover-domain code)
--------------------------------------------------------------------
The bearing ``b`` of an object is measured counter-clockwise from the rover's heading and
wrapped to ``[-pi, pi)``; the quadrant is ``q = floor((b + pi) / (pi / 2))``:

====  ==============  ====================
 q    name            bearings
====  ==============  ====================
 0    behind-right    [-180 deg, -90 deg)
 1    front-right     [-90 deg, 0)
 2    front-left      [0, 90 deg)
 3    behind-left     [90 deg, 180 deg)
====  ==============  ====================

A bearing on a boundary goes to the quadrant that starts there (dead ahead -> 2, dead
right -> 1, dead left -> 3, dead behind -> 0). The bearing is read from the object's offset
``(f, l)`` in the rover's frame (``f`` forward, ``l`` left) as ``atan2(l, f)``, so an object
at the rover's own position (offset 0) has bearing 0 and lies in quadrant 2. The code uses
the signs of ``f`` and ``l`` instead of ``atan2``: the same answer, exact on the boundaries.
Other sector counts use ``floor((atan2(l, f) + pi) n / (2 pi))`` with a bearing of exactly
pi sent to sector 0: the same rule, up to atan2's rounding on a boundary.

The lab's code computes ``floor((atan2(l, f) + pi) / (2 pi) * 4)`` clipped to 0-3, which
agrees except for signed zeros: dead behind with ``l = +0`` (what its arithmetic gives for
heading 0) is its quadrant 3 (here 0), and a coincident object is its quadrant 3 when the
heading's cosine and sine are both negative (here always 2).

The lidar's ``bearing = "world"`` measures sectors from the +x axis instead, whatever the
heading (:func:`world_sector`, the lab's ``l2a``).
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit


@jit
def quadrant(forward: float, left: float) -> int:
    """Quadrant of an offset (forward, left) in the rover's frame (module docstring).

    Branch-free (the quadrants of random objects defeat branch prediction): bit 1 is the
    half (bearing in [0, pi), dead ahead and the rover's own spot included), bit 0 the
    quadrant within it (behind in the upper half, dead left included; front in the lower
    half, dead right included).
    """
    upper = np.int64((left > 0.0) | ((left == 0.0) & (forward >= 0.0)))
    behind = np.int64((forward < 0.0) | ((forward == 0.0) & (left > 0.0)))
    ahead = np.int64(forward >= 0.0)
    low = (upper & behind) | ((1 - upper) & ahead)
    return 2 * upper + low


@jit
def sector(forward: float, left: float, n_sectors: int) -> int:
    """Sector (0 .. n - 1) of an offset (forward, left) in the rover's frame: n equal
    sectors of bearing counter-clockwise from dead behind, a boundary bearing in the sector
    that starts there. Four sectors: :func:`quadrant` (exact on the boundaries); otherwise
    ``floor((atan2(left, forward) + pi) n / (2 pi))``, a bearing of pi (dead behind) in
    sector 0."""
    if n_sectors == 4:
        return quadrant(forward, left)
    q = np.int64(math.floor((math.atan2(left, forward) + math.pi) * n_sectors / (2 * math.pi)))
    return q if q < n_sectors else 0


@jit
def world_sector(dx: float, dy: float, n_sectors: int) -> int:
    """The lab's ``l2a`` sector of an offset (dx, dy) in the world frame: ``atan2`` in
    degrees, +360 if negative, ``int(angle / (360 / n))``, 360 -> 0."""
    angle = math.degrees(math.atan2(dy, dx))
    if angle < 0.0:
        angle += 360.0
    q = np.int64(angle / (360.0 / n_sectors))
    return q if q < n_sectors else 0


__all__ = ["quadrant", "sector", "world_sector"]
