"""The broad phase of everything local: which pairs of points of a team lie within a reach.

The contact pass (:func:`physrover.domain.motion.contacts.speculative_contacts`) needs the
pairs (i, j), i < j, of a team's rovers closer than the distance they could close within a
physics step; a sensor with a finite radius the neighbours within its radius; the spawn's
separation the pairs that overlap. Listing them by testing every pair
(:func:`near_pairs_all`) costs R (R - 1) / 2 distance tests, which dominates at hundreds
of rovers. :func:`near_pairs_grid` lists the same pairs, in the same order (i ascending,
then j ascending), from a cell list:

1. :func:`grid`: each point falls in a square cell of side ``reach`` (slightly more, so
   rounding never puts two points closer than ``reach`` two cells apart) over the points'
   bounding box; a counting sort puts the points in cell order (column by column), so
   cells (cx, cy - 1 .. cy + 1) are one run of that order;
2. each pair is tested once, from its first point in cell order (a half stencil): against
   the rest of its cell and the cell above, one run, and the next column's three cells,
   another; branch-free, in the cell order's copy of the coordinates;
3. the pairs found are counted by their lower index and sorted by insertion within it.

The cost is O(R + candidates + pairs) a team instead of O(R^2). Below
:data:`GRID_MIN_POINTS` points (:data:`SENSOR_GRID_MIN_POINTS` for the sensor, whose
all-pairs loop is vectorised) testing every pair is faster and is used; both return
identical lists (tested on random layouts, cell boundaries, crowds, impacts and columns
against walls), so a team's results do not depend on which one ran. Coincident points
(squared distance below 1e-24) are listed only when asked (``inclusive``): a contact has
no normal for them.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from physrover.core.compiled import jit, jit_inline

GRID_MIN_POINTS = 80
"""Teams of at least this many rovers find their contact pairs, and their spawn's
overlaps, from the grid; smaller ones test every pair. Measured (2026-12-03, EPYC Zen 4,
one thread, teams spread as ``physrover bench world --rovers`` spreads them, reach 0.9):
listing the pairs costs the same both ways at 75 rovers, the grid 1.5x less at 100, 5x
at 300, 17x at 1000 (``benchmarks/scaling_vs_vmas.py`` has the whole world's scaling)."""

SENSOR_GRID_MIN_POINTS = 100
"""Teams of at least this many rovers find the neighbours of a sensor with a finite radius
from the grid. The all-pairs sensor is vectorised over 16 observing rovers at a time and
wins in small teams. Measured (2026-12-03, EPYC Zen 4, one thread, radius 5, teams spread as
``physrover bench world --rovers`` spreads them, layouts changing every step), us to sense
1500 rovers: all-pairs 43 / 127 / 172 / 284 / 457 at 15 / 75 / 100 / 200 / 400 rovers a
team, the grid 150-170 throughout (``benchmarks/scaling_vs_vmas.py``). A denser team (more
neighbours within the radius) moves the crossover up."""

_CELL_MARGIN = 1.0 + 1e-9
"""A cell is this much wider than the reach: two points closer than the reach then always
fall in neighbouring cells, whatever the rounding of p / cell."""


if numba.config.DISABLE_JIT:  # plain Python (NUMBA_DISABLE_JIT=1): the same index

    def _trailing_zeros(bits):
        bits = int(bits)
        return (bits & -bits).bit_length() - 1

else:
    from numba.cpython.unsafe.numbers import trailing_zeros as _trailing_zeros


@jit_inline
def mark(marks, j, keep=True):
    """Add index ``j`` >= 0 to the set ``marks``, (ceil(n / 64),) uint64 words of bits, if
    ``keep`` (without a branch: a test a branch predictor cannot learn costs less so)."""
    marks[j >> 6] |= np.uint64(keep) << np.uint64(j & 63)


@jit_inline
def drain_ascending(marks, out):
    """Write the indices in the set ``marks`` (:func:`mark`) to ``out`` in ascending order
    and empty the set; returns how many. O(indices + words), where sorting them (by
    insertion) was O(indices^2): a UAV of ``benchmarks/configs/mixed200.toml`` has ~36
    agents in the cells its radius reaches."""
    n = 0
    for w in range(marks.shape[0]):
        bits = marks[w]
        while bits != 0:
            out[n] = w * 64 + np.int64(_trailing_zeros(bits))
            n += 1
            bits &= bits - np.uint64(1)
        marks[w] = 0
    return n


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
def grid(points, reach):
    """The cell list of (R, 2) ``points`` for a ``reach`` > 0: square cells of side at
    least ``reach`` over the points' bounding box, at most ``4 R + 16`` of them (a sparse
    spread doubles the side until it fits: more candidates, the same neighbours). A point
    with a NaN or infinite coordinate is in no cell (cells[i] = -1): it has no finite
    distance to anything, and testing every pair would list it with nothing either.

    Returns ``(cells, nx, ny, starts, members, ordered)``: point i's cell column and row
    ``cells[i]`` (cx, cy = floor((p - p_min) / side)) in a grid of nx columns and ny rows;
    the points of cell c = cx ny + cy, ``members[starts[c]:starts[c + 1]]``, ascending (a
    counting sort: no comparison sort, no search); and their coordinates in the same
    order, ``ordered = points[members]`` (the neighbour scans then read memory in
    sequence)."""
    n = points.shape[0]
    x0 = y0 = np.inf
    x1 = y1 = -np.inf
    n_finite = 0
    for i in range(n):
        if math.isfinite(points[i, 0]) and math.isfinite(points[i, 1]):
            x0, x1 = min(x0, points[i, 0]), max(x1, points[i, 0])
            y0, y1 = min(y0, points[i, 1]), max(y1, points[i, 1])
            n_finite += 1
    if n_finite == 0:
        x0 = x1 = y0 = y1 = 0.0
    side = reach * _CELL_MARGIN
    while (math.floor((x1 - x0) / side) + 1) * (math.floor((y1 - y0) / side) + 1) > 4 * n + 16:
        side *= 2.0
    nx = np.int64(math.floor((x1 - x0) / side)) + 1
    ny = np.int64(math.floor((y1 - y0) / side)) + 1
    cells = np.full((n, 2), -1, np.int64)  # a NaN or infinite point: in no cell
    starts = np.zeros(nx * ny + 1, np.int64)
    for i in range(n):
        if math.isfinite(points[i, 0]) and math.isfinite(points[i, 1]):
            cells[i, 0] = min(np.int64(math.floor((points[i, 0] - x0) / side)), nx - 1)
            cells[i, 1] = min(np.int64(math.floor((points[i, 1] - y0) / side)), ny - 1)
            starts[cells[i, 0] * ny + cells[i, 1] + 1] += 1
    for c in range(nx * ny):
        starts[c + 1] += starts[c]
    members = np.empty(n_finite, np.int64)
    ordered = np.empty((n_finite, 2))
    fill = starts[:-1].copy()
    for i in range(n):
        if cells[i, 0] < 0:
            continue
        c = cells[i, 0] * ny + cells[i, 1]
        members[fill[c]] = i
        ordered[fill[c], 0], ordered[fill[c], 1] = points[i, 0], points[i, 1]
        fill[c] += 1
    return cells, nx, ny, starts, members, ordered


@jit_inline
def stencil_runs(slot, cell_x, cell_y, nx, ny, starts):
    """The half stencil of the point in ``slot`` of the cell order (cell (cell_x, cell_y)
    of :func:`grid`): two runs ``((start, end), (start, end))`` of the cell order, the rest
    of its own cell with the cell above, and the next column's three cells (empty at the
    last column). Every pair of points in neighbouring cells is in exactly one of the two
    points' half stencils: the one earlier in the cell order."""
    own_end = starts[cell_x * ny + min(cell_y + 1, ny - 1) + 1]
    if cell_x + 1 < nx:
        column = (cell_x + 1) * ny
        return ((slot + 1, own_end), (starts[column + max(cell_y - 1, 0)],
                                      starts[column + min(cell_y + 1, ny - 1) + 1]))  # fmt: skip
    return ((slot + 1, own_end), (np.int64(0), np.int64(0)))


@jit
def near_pairs_grid(points, reach_sq, near, inclusive=False):
    """:func:`near_pairs_all` from the cell list (:func:`grid`): the same pairs in the same
    order; with ``inclusive`` the pairs with squared distance <= ``reach_sq``, coincident
    ones too (a sensor's neighbours). ``near`` grows (a new array is returned) when the
    pairs outnumber its rows; returns (count, near).

    Each pair is tested once (a half stencil): a point in cell (cx, cy) is tested against
    the points after it in its own cell and in (cx, cy + 1), one run of the cell order,
    and against the column (cx + 1, cy - 1 .. cy + 1), another. The pairs found, (lower
    index, higher), are then put in index order: counted by their lower index (a counting
    sort), each point's higher indices sorted by insertion."""
    n = points.shape[0]
    if n < 2:
        return 0, near
    cells, nx, ny, starts, members, ordered = grid(points, math.sqrt(reach_sq))
    found = np.empty((max(near.shape[0], 2 * n), 2), np.int64)  # unordered, then ordered
    first_of = np.zeros(n + 1, np.int64)  # pairs per lower index, then where they start
    n_found = 0
    for slot in range(members.shape[0]):
        a = members[slot]
        xa, ya = ordered[slot, 0], ordered[slot, 1]
        runs = stencil_runs(slot, cells[a, 0], cells[a, 1], nx, ny, starts)
        room = (runs[0][1] - runs[0][0]) + (runs[1][1] - runs[1][0])
        if n_found + room > found.shape[0]:
            grown = np.empty((2 * (n_found + room), 2), np.int64)
            grown[:n_found] = found[:n_found]
            found = grown
        for run in runs:
            for other in range(run[0], run[1]):
                # branch-free: written, kept only if within reach (random layouts defeat
                # branch prediction)
                b = members[other]
                dx = ordered[other, 0] - xa
                dy = ordered[other, 1] - ya
                d_sq = dx * dx + dy * dy
                within = (d_sq <= reach_sq) if inclusive else (d_sq < reach_sq) & (d_sq >= 1e-24)
                low = min(a, b)
                found[n_found, 0], found[n_found, 1] = low, a + b - low
                n_found += within
    for k in range(n_found):
        first_of[found[k, 0] + 1] += 1
    for i in range(n):
        first_of[i + 1] += first_of[i]
    if n_found > near.shape[0]:
        near = np.empty((2 * n_found, 2), np.int64)
    fill = first_of[:n].copy()
    for k in range(n_found):
        i = found[k, 0]
        near[fill[i], 0], near[fill[i], 1] = i, found[k, 1]
        fill[i] += 1
    for i in range(n):  # each point's higher indices, ascending (insertion: a few each)
        for k in range(first_of[i] + 1, first_of[i + 1]):
            j, row = near[k, 1], k
            while row > first_of[i] and near[row - 1, 1] > j:
                near[row, 1] = near[row - 1, 1]
                row -= 1
            near[row, 1] = j
    return n_found, near


@jit
def near_pairs(points, reach_sq, near):
    """The pairs within reach of (R, 2) ``points`` (:func:`near_pairs_all`'s list), from
    the grid from :data:`GRID_MIN_POINTS` points on; returns (count, near), ``near``
    replaced by a larger array where it had too few rows."""
    if points.shape[0] >= GRID_MIN_POINTS:
        return near_pairs_grid(points, reach_sq, near)
    return near_pairs_all(points, reach_sq, near), near
