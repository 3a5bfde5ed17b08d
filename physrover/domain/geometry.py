"""Rover-to-object relations of one time step: bounded distances (Eq. 14) and quadrants.

Every rover relates to N = R + K objects: the R rovers of its team (itself included, masked
by the callers) followed by the K POIs. Both sensing (Eqs. 15-16) and scoring (Eqs. 12-13)
read these arrays, so the pairwise distances are computed once per step.

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

Precision: relations are computed in float32 (positions are kept in float64 by the world).
Observations are float32 anyway, and this halves the cost of the hot path; a capture
decision can differ from a float64 computation only for a rover within ~1e-6 world units of
the capture circle. (The compiled kernel of :mod:`physrover.domain.kernels`, the default
engine, computes them in float64.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DTYPE = np.float32


@dataclass(frozen=True)
class Relations:
    """Relations of every rover to every object of its team at one step.

    Attributes:
        delta_sq: (E, R, N) float32 squared bounded distance ``max(||p_i - p_j||, d_min)^2``
            (Eq. 14), world units squared; objects are the R rovers, then the K POIs.
        quadrant: (E, R, N) uint8 quadrant of each object in the rover's frame (module doc).
    """

    delta_sq: np.ndarray
    quadrant: np.ndarray


def quadrants(forward: np.ndarray, left: np.ndarray) -> np.ndarray:
    """Quadrant index (uint8) of offsets given in the rover's frame; see the module docstring."""
    upper = left > 0  # bearing in [0, pi) ...
    upper |= (left == 0) & (forward >= 0)  # ... including dead ahead and the rover's own spot
    behind = forward < 0  # in the upper half: bearing in [pi/2, pi) ...
    behind |= (forward == 0) & (left > 0)  # ... including dead left
    # Bit 1 is the half, bit 0 the quadrant within it; boolean algebra instead of np.where,
    # which branches per element and costs ten times more on mixed signs.
    low = (upper & behind) | (~upper & (forward >= 0))
    return (upper.view(np.uint8) << 1) | low.view(np.uint8)


def relate(
    rover_positions: np.ndarray,
    rover_headings: np.ndarray,
    poi_positions: np.ndarray,
    d_min: float,
) -> Relations:
    """Relations of each rover to all rovers and POIs of its team.

    Args:
        rover_positions: (E, R, 2) world positions.
        rover_headings: (E, R) headings, radians counter-clockwise from the world x axis.
        poi_positions: (E, K, 2) world positions.
        d_min: lower bound of the distance metric (Eq. 14), world units.
    """
    objects = np.concatenate([rover_positions, poi_positions], axis=1).astype(DTYPE)
    # Coordinates as contiguous (E, R) / (E, N) arrays: broadcasting over a trailing axis of
    # size 2 is several times slower than these plain outer differences.
    ox, oy = np.ascontiguousarray(objects[..., 0]), np.ascontiguousarray(objects[..., 1])
    n_rovers = rover_positions.shape[1]
    rx, ry = ox[:, :n_rovers], oy[:, :n_rovers]
    dx = ox[:, None, :] - rx[:, :, None]  # (E, R, N)
    dy = oy[:, None, :] - ry[:, :, None]
    headings = rover_headings.astype(DTYPE)[..., None]
    cos_h, sin_h = np.cos(headings), np.sin(headings)
    forward = cos_h * dx
    forward += sin_h * dy
    left = cos_h * dy
    left -= sin_h * dx
    delta_sq = dx * dx
    delta_sq += dy * dy
    np.maximum(delta_sq, DTYPE(d_min * d_min), out=delta_sq)
    return Relations(delta_sq=delta_sq, quadrant=quadrants(forward, left))
