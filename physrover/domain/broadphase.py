"""The broad phase of everything local: which pairs of points of a team lie within a reach.

The contact pass (:func:`physrover.domain.physics_kernels.speculative_contacts`) needs the
pairs (i, j), i < j, of a team's rovers closer than the distance they could close within a
physics step; listing them by testing every pair costs R (R - 1) / 2 distance tests a
physics step, which dominates at hundreds of rovers. :func:`near_pairs` lists the same
pairs, in the same order (i ascending, then j ascending), from a uniform grid:

1. each point falls in a square cell of side ``reach`` (slightly more, so rounding never
   puts two points closer than ``reach`` two cells apart), cell (cx, cy) =
   floor(p / cell);
2. the points are sorted by the cell's key ``(cx - cx_min + 1) W + (cy - cy_min + 1)``
   (W the key's row width), so each column of three neighbouring cells is one run of keys;
3. each point i looks up the three runs of the 3 x 3 cells around its own (binary
   search), keeps the j > i within reach, and sorts those by index.

The cost is O(R log R + pairs) a team instead of O(R^2). Below
:data:`GRID_MIN_POINTS` points the all-pairs loop (:func:`near_pairs_all`) is faster and
is used; both return identical lists (tested on crowds, impacts and columns against
walls). Coincident points (distance below 1e-12) are never listed: they have no normal.
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit

GRID_MIN_POINTS = 48
"""Teams of at least this many rovers take the grid; smaller ones test every pair."""

_CELL_MARGIN = 1.0 + 1e-9
"""A cell is this much wider than the reach: two points closer than the reach then always
fall in neighbouring cells, whatever the rounding of p / cell."""


@jit
def near_pairs_all(points, reach_sq, near):
    """The pairs (i, j), i < j, of (R, 2) ``points`` with squared distance in
    [1e-24, ``reach_sq``), in index order, written to ``near`` (at least R (R - 1) / 2 rows
    of 2); returns how many."""
    n_near = 0
    for i in range(points.shape[0]):
        for j in range(i + 1, points.shape[0]):
            dx = points[j, 0] - points[i, 0]
            dy = points[j, 1] - points[i, 1]
            d_sq = dx * dx + dy * dy
            if d_sq < reach_sq and d_sq >= 1e-24:
                near[n_near, 0], near[n_near, 1] = i, j
                n_near += 1
    return n_near


@jit
def near_pairs_grid(points, reach_sq, near):
    """:func:`near_pairs_all` from a uniform grid (the module docstring): the same pairs in
    the same order. ``near`` grows (a new array is returned) when the pairs outnumber its
    rows; returns (count, near)."""
    n = points.shape[0]
    cell = math.sqrt(reach_sq) * _CELL_MARGIN
    cx = np.empty(n, np.int64)
    cy = np.empty(n, np.int64)
    for i in range(n):
        cx[i] = np.int64(math.floor(points[i, 0] / cell))
        cy[i] = np.int64(math.floor(points[i, 1] / cell))
    x0, y0 = cx.min(), cy.min()
    width = cy.max() - y0 + 3
    keys = (cx - x0 + 1) * width + (cy - y0 + 1)
    order = np.argsort(keys, kind="mergesort")
    sorted_keys = keys[order]
    found = np.empty(n, np.int64)
    n_near = 0
    for i in range(n):
        n_found = 0
        for column in range(-1, 2):
            centre = keys[i] + column * width
            lo = np.searchsorted(sorted_keys, centre - 1, side="left")
            hi = np.searchsorted(sorted_keys, centre + 1, side="right")
            for slot in range(lo, hi):
                j = order[slot]
                if j <= i:
                    continue
                dx = points[j, 0] - points[i, 0]
                dy = points[j, 1] - points[i, 1]
                d_sq = dx * dx + dy * dy
                if d_sq < reach_sq and d_sq >= 1e-24:
                    found[n_found] = j
                    n_found += 1
        if n_near + n_found > near.shape[0]:
            grown = np.empty((2 * (n_near + n_found), 2), np.int64)
            grown[:n_near] = near[:n_near]
            near = grown
        found[:n_found].sort()
        for k in range(n_found):
            near[n_near, 0], near[n_near, 1] = i, found[k]
            n_near += 1
    return n_near, near


@jit
def near_pairs(points, reach_sq, near):
    """The pairs within reach of (R, 2) ``points`` (:func:`near_pairs_all`'s list), from
    the grid from :data:`GRID_MIN_POINTS` points on; returns (count, near), ``near``
    replaced by a larger array where it had too few rows."""
    if points.shape[0] >= GRID_MIN_POINTS:
        return near_pairs_grid(points, reach_sq, near)
    return near_pairs_all(points, reach_sq, near), near
