"""Compiled kernels of the world step (see :mod:`physrover.engine`).

:func:`observe_and_score` is relations (Eq. 14 and the quadrants of
:mod:`physrover.domain.geometry`) + sensing (Eqs. 15-16, :mod:`physrover.domain.sensing`)
+ scoring of one step (Eqs. 12-13 and the counterfactual counts of D,
:mod:`physrover.domain.scoring`) in one pass over the rover-object pairs;
:func:`ideal_move` is the idealised kinematics of :mod:`physrover.domain.motion`. The numpy
modules named are the reference these kernels are tested against.

Precision: everything is computed in float64 (the numpy reference computes relations in
float32); observations are returned as float32 either way. Sensor sums add the objects in
the same order as the reference (rovers by index, then POIs).
"""

from __future__ import annotations

import math

import numpy as np

from physrover.engine import jit


@jit
def quadrant(forward: float, left: float) -> int:
    """Quadrant of an offset (forward, left) in the rover's frame, as ``geometry.quadrants``.

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
def observe_and_score(
    rover_positions,  # (E, R, 2) float64
    rover_headings,  # (E, R) float64
    poi_positions,  # (E, K, 2) float64
    poi_values,  # (E, K) float64
    d_min,
    d_cap,
    n_req,
    t,
    captured,  # (E, K) bool, updated
    captured_without,  # (E, R, K) bool, updated
    capture_step,  # (E, K) int64, updated
    obs,  # (E, R, 8) float32, written
):
    """Sense (Eqs. 15-16) and score (Eqs. 12-13) step ``t`` for every team, in place.

    ``captured``, ``captured_without`` and ``capture_step`` are the arrays of a
    :class:`~physrover.domain.scoring.ScoreKeeper`, advanced exactly as its ``record`` does.
    Each sensor channel adds its terms object by object in the reference's order.
    """
    n_teams, n_rovers = rover_headings.shape
    n_pois = poi_positions.shape[1]
    d_min_sq = d_min * d_min
    d_cap_sq = d_cap * d_cap
    count = np.zeros(n_pois, np.int64)
    near = np.zeros((n_rovers, n_pois), np.int64)
    acc = np.zeros(8)
    for e in range(n_teams):
        count[:] = 0
        for i in range(n_rovers):
            cos_h = math.cos(rover_headings[e, i])
            sin_h = math.sin(rover_headings[e, i])
            xi = rover_positions[e, i, 0]
            yi = rover_positions[e, i, 1]
            acc[:] = 0.0
            for j in range(n_rovers):  # Eq. 15: the other rovers, numerator 1
                if j == i:
                    continue
                dx = rover_positions[e, j, 0] - xi
                dy = rover_positions[e, j, 1] - yi
                dist_sq = max(dx * dx + dy * dy, d_min_sq)  # Eq. 14
                q = quadrant(cos_h * dx + sin_h * dy, cos_h * dy - sin_h * dx)
                acc[q] += 1.0 / dist_sq
            for k in range(n_pois):  # Eq. 16: the POIs, numerator V_k
                dx = poi_positions[e, k, 0] - xi
                dy = poi_positions[e, k, 1] - yi
                dist_sq = max(dx * dx + dy * dy, d_min_sq)
                q = quadrant(cos_h * dx + sin_h * dy, cos_h * dy - sin_h * dx)
                acc[4 + q] += poi_values[e, k] / dist_sq
                inside = np.int64(dist_sq <= d_cap_sq)  # Eq. 13
                near[i, k] = inside
                count[k] += inside
            for c in range(8):
                obs[e, i, c] = acc[c]
        for k in range(n_pois):
            if count[k] >= n_req:  # Eq. 12
                if not captured[e, k]:
                    capture_step[e, k] = t
                    captured[e, k] = True
            for i in range(n_rovers):  # Eq. 12 without rover i
                if count[k] - near[i, k] >= n_req:
                    captured_without[e, i, k] = True


@jit
def ideal_move(positions, headings, actions, new_positions, new_headings):
    """The idealised move (``motion.IdealMotion.step``) of (E, R) rovers into the outputs."""
    n_teams, n_rovers = headings.shape
    for e in range(n_teams):
        for i in range(n_rovers):
            heading = headings[e, i]
            cos_h = math.cos(heading)
            sin_h = math.sin(heading)
            fwd = np.float64(actions[e, i, 0])
            left = np.float64(actions[e, i, 1])
            mx = cos_h * fwd - sin_h * left
            my = sin_h * fwd + cos_h * left
            new_positions[e, i, 0] = positions[e, i, 0] + mx
            new_positions[e, i, 1] = positions[e, i, 1] + my
            new_headings[e, i] = math.atan2(my, mx) if (fwd != 0.0 or left != 0.0) else heading
