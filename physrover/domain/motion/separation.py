"""Overlapping spawns pushed apart: rovers placed on each other by a scenario (or by
``reset(options=...)``) are moved until no pair overlaps by more than a tolerance, before
the physical world takes them (:meth:`physrover.domain.motion.physics.PhysicsMotion.reset`).

:func:`separate` is the entry point; :func:`separate_teams` its compiled loop, which tests
every pair in small teams and takes the pairs from the grid
(:mod:`physrover.domain.broadphase`) in large ones, with the same result bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit
from physrover.domain.broadphase import GRID_MIN_POINTS, near_pairs_grid


def separate(
    positions: np.ndarray,
    min_distance,
    tolerance: float,
    max_iterations: int = 500,
    symmetric: bool | None = None,
) -> np.ndarray:
    """Push overlapping points of each team apart until no pair is closer than
    ``min_distance - tolerance`` (a scalar, or (R, R) per pair; ``symmetric`` says
    whether that matrix equals its transpose, which lets large teams take the grid; None:
    checked here, an R^2 comparison at every call).

    Each iteration moves both points of every overlapping pair apart by half the overlap
    plus ``tolerance`` along the line joining them (coincident points along a direction
    fixed by their indices), all pairs from the positions at the iteration's start; a team
    stops when none of its pairs overlaps by more than ``tolerance``
    (:func:`separate_teams`). Deterministic; (E, R, 2)
    in, (E, R, 2) out.
    """
    n_rovers = positions.shape[1]
    contact = np.broadcast_to(np.asarray(min_distance, dtype=np.float64), (n_rovers, n_rovers))
    x, y = positions[..., 0].astype(np.float64), positions[..., 1].astype(np.float64)
    if symmetric is None:
        symmetric = bool(np.array_equal(contact, contact.T))
    separate_teams(x, y, np.ascontiguousarray(contact), float(tolerance), max_iterations,
                   symmetric)  # fmt: skip
    return np.stack([x, y], axis=-1)


@jit
def _overlap(x, y, i, j, min_distance):
    """Points i and j of (R,) ``x``, ``y``: their distance, the offset from j to i, and
    the overlap max(min_distance - distance, 0); ``(dist, dx, dy, overlap)``."""
    dx, dy = x[i] - x[j], y[i] - y[j]
    dist = math.sqrt(dx * dx + dy * dy)
    return dist, dx, dy, max(min_distance[i, j] - dist, 0.0)


@jit
def _push_of(i, j, dist, dx, dy, overlap, min_distance, tolerance):
    """Point i's push away from j for a positive ``overlap`` (:func:`_overlap`): half the
    overlap plus ``tolerance`` along the offset, or, for coincident points, along the
    angle ``2.399963 (i + j)``, ``sign(i - j)`` times ``min_distance``; (px, py). Swapping
    i and j negates it exactly."""
    if dist > 1e-12:
        scale = (0.5 * overlap + tolerance) / dist
        return dx * scale, dy * scale
    side = (i > j) - (i < j)
    return (side * math.cos(2.399963 * (i + j)) * min_distance[i, j],
            side * math.sin(2.399963 * (i + j)) * min_distance[i, j])  # fmt: skip


@jit
def separate_teams(x, y, min_distance, tolerance, max_iterations, symmetric):
    """:func:`separate` in place on (E, R) coordinates ``x``, ``y``, team by team;
    ``min_distance`` (R, R). Each pair's push (:func:`_push_of`) is summed per point in
    index order. A ``symmetric`` ``min_distance`` in a team of at least
    :data:`~physrover.domain.broadphase.GRID_MIN_POINTS` takes the cell list
    (:func:`_separate_near`): the same pushes, bit for bit."""
    n_teams, n_rovers = x.shape
    push_x, push_y = np.empty(n_rovers), np.empty(n_rovers)
    for e in range(n_teams):
        xe, ye = x[e], y[e]
        if symmetric and n_rovers >= GRID_MIN_POINTS:
            _separate_near(xe, ye, min_distance, tolerance, max_iterations, push_x, push_y)
            continue
        for _ in range(max_iterations):
            crowded = False
            for i in range(n_rovers):
                sx = sy = 0.0
                for j in range(n_rovers):
                    if j == i:
                        continue
                    dist, dx, dy, overlap = _overlap(xe, ye, i, j, min_distance)
                    crowded = crowded or overlap > tolerance
                    if overlap > 0.0:
                        px, py = _push_of(i, j, dist, dx, dy, overlap, min_distance, tolerance)
                        sx += px
                        sy += py
                push_x[i], push_y[i] = sx, sy
            if not crowded:
                break
            for i in range(n_rovers):
                xe[i] += push_x[i]
                ye[i] += push_y[i]


@jit
def _separate_near(x, y, min_distance, tolerance, max_iterations, push_x, push_y):
    """:func:`separate_teams` for one team's (R,) ``x``, ``y`` from the pairs within the
    widest ``min_distance`` (:func:`physrover.domain.broadphase.near_pairs_grid`, index
    order): each pair (i, j), i < j, pushes both points, j by the exact negation of i's
    push, so each point sums its pushes in ascending index order as the all-pairs loop
    does (pairs farther apart push nothing there)."""
    n = x.shape[0]
    widest = 0.0
    for i in range(n):
        for j in range(n):
            widest = max(widest, min_distance[i, j])
    reach_sq = (widest * (1.0 + 1e-9)) ** 2  # every pair with dist < min_distance, and more
    points = np.empty((n, 2))
    near = np.empty((8 * n, 2), np.int64)
    for _ in range(max_iterations):
        points[:, 0], points[:, 1] = x, y
        n_near, near = near_pairs_grid(points, reach_sq, near, True)
        push_x[:], push_y[:] = 0.0, 0.0
        crowded = False
        for k in range(n_near):
            i, j = near[k, 0], near[k, 1]
            dist, dx, dy, overlap = _overlap(x, y, i, j, min_distance)
            crowded = crowded or overlap > tolerance
            if overlap > 0.0:
                px, py = _push_of(i, j, dist, dx, dy, overlap, min_distance, tolerance)
                push_x[i] += px
                push_y[i] += py
                push_x[j] -= px
                push_y[j] -= py
        if not crowded:
            break
        for i in range(n):
            x[i] += push_x[i]
            y[i] += push_y[i]


def pair_overlaps(positions: np.ndarray, radius: float) -> np.ndarray:
    """(E, R (R - 1) / 2) overlap of every pair of rovers of each team, as a fraction of a
    diameter: ``max(0, 2 r - distance) / (2 r)`` (0 apart or touching, 1 coincident)."""
    d = positions[:, :, None, :] - positions[:, None, :, :]
    dist = np.sqrt((d**2).sum(-1))
    i, j = np.triu_indices(positions.shape[1], 1)
    return np.maximum(0.0, 2 * radius - dist[:, i, j]) / (2 * radius)
