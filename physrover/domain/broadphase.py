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

:func:`neighbour_lists` is the same grid for a sensor with a finite radius: every point's
neighbours within the radius (inclusive, coincident ones too), ascending.
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit

GRID_MIN_POINTS = 4096
"""Teams of at least this many rovers take the grid; smaller ones test every pair.
Provisional: measured at 100 rovers (2026-12-02, EPYC Zen 4) the grid made the physical
world 1.6x and a radius-5 sensor 4.7x slower than testing every pair, so it is off at
every team size measured until the crossover is measured (issue 32)."""

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
def _grid(points, cell):
    """The grid of (R, 2) ``points`` with square cells of side ``cell``: each point's key,
    the points in key order, the sorted keys, and the key's row width."""
    n = points.shape[0]
    cx = np.empty(n, np.int64)
    cy = np.empty(n, np.int64)
    for i in range(n):
        cx[i] = np.int64(math.floor(points[i, 0] / cell))
        cy[i] = np.int64(math.floor(points[i, 1] / cell))
    x0, y0 = cx.min(), cy.min()
    width = cy.max() - y0 + 3
    keys = (cx - x0 + 1) * width + (cy - y0 + 1)
    order = np.argsort(keys, kind="mergesort")
    return keys, order, keys[order], width


@jit
def _neighbours(points, i, reach_sq, inclusive, above, keys, order, sorted_keys, width, found):
    """The points j (j > i if ``above``, else every j != i) within reach of point i, from
    the 3 x 3 cells around its own, written to ``found`` unsorted; returns how many. Within
    reach: squared distance < ``reach_sq`` and >= 1e-24, or <= ``reach_sq`` if
    ``inclusive`` (then coincident points count too)."""
    n_found = 0
    for column in range(-1, 2):
        centre = keys[i] + column * width
        lo = np.searchsorted(sorted_keys, centre - 1, side="left")
        hi = np.searchsorted(sorted_keys, centre + 1, side="right")
        for slot in range(lo, hi):
            j = order[slot]
            if j == i or (above and j < i):
                continue
            dx = points[j, 0] - points[i, 0]
            dy = points[j, 1] - points[i, 1]
            d_sq = dx * dx + dy * dy
            if (d_sq <= reach_sq) if inclusive else (reach_sq > d_sq >= 1e-24):
                found[n_found] = j
                n_found += 1
    return n_found


@jit
def near_pairs_grid(points, reach_sq, near):
    """:func:`near_pairs_all` from a uniform grid (the module docstring): the same pairs in
    the same order. ``near`` grows (a new array is returned) when the pairs outnumber its
    rows; returns (count, near)."""
    n = points.shape[0]
    keys, order, sorted_keys, width = _grid(points, math.sqrt(reach_sq) * _CELL_MARGIN)
    found = np.empty(n, np.int64)
    n_near = 0
    for i in range(n):
        n_found = _neighbours(points, i, reach_sq, False, True, keys, order, sorted_keys,
                              width, found)  # fmt: skip
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
def neighbour_lists(points, radius_sq):
    """For each of (R, 2) ``points``, the others within ``sqrt(radius_sq)`` (squared
    distance <= ``radius_sq``, coincident points included), ascending, from the grid:
    ``(starts, items)``, point i's list ``items[starts[i]:starts[i + 1]]``."""
    n = points.shape[0]
    keys, order, sorted_keys, width = _grid(points, math.sqrt(radius_sq) * _CELL_MARGIN)
    found = np.empty(n, np.int64)
    starts = np.empty(n + 1, np.int64)
    items = np.empty(8 * n, np.int64)
    count = 0
    for i in range(n):
        starts[i] = count
        n_found = _neighbours(points, i, radius_sq, True, False, keys, order, sorted_keys,
                              width, found)  # fmt: skip
        if count + n_found > items.shape[0]:
            grown = np.empty(2 * (count + n_found), np.int64)
            grown[:count] = items[:count]
            items = grown
        found[:n_found].sort()
        items[count : count + n_found] = found[:n_found]
        count += n_found
    starts[n] = count
    return starts, items


@jit
def near_pairs(points, reach_sq, near):
    """The pairs within reach of (R, 2) ``points`` (:func:`near_pairs_all`'s list), from
    the grid from :data:`GRID_MIN_POINTS` points on; returns (count, near), ``near``
    replaced by a larger array where it had too few rows."""
    if points.shape[0] >= GRID_MIN_POINTS:
        return near_pairs_grid(points, reach_sq, near)
    return near_pairs_all(points, reach_sq, near), near
