"""Compiled kernels of the world step: the one implementation of Eqs. 11-16 and of the
idealised motion (Section 4.1.2).

- :func:`observe_and_score`: relations (Eq. 14 and the quadrants of
  :mod:`physrover.domain.sensing`) + sensing (Eqs. 15-16) + scoring of one step (Eqs. 11-13
  and the counterfactual counts of D, :mod:`physrover.domain.scoring`) in one pass over the
  rover-object pairs;
- :func:`ideal_step`: a whole idealised world step in one call (check and clip the actions,
  move, observe, score, record), so that a step costs one call instead of a dozen.

The tests compare them with plain numpy versions of the same equations (``tests/oracles.py``)
and with hand-worked values. Run with ``NUMBA_DISABLE_JIT=1`` they are plain Python, for
debugging.

Precision: everything is computed in float64; observations are returned as float32. Sensor
sums add the objects in a fixed order (rovers by index, then POIs); G sums the captured
values in POI order.

Headings enter the kernels as their cosine and sine, ``cos_h`` and ``sin_h`` (E, R), kept by
the world next to the headings: a step needs those of the old heading (to move) and of the
new one (to sense), and the old one's are the previous step's new one's. After a reset (and
under physical motion) they are ``cos`` and ``sin`` of the heading (:func:`heading_trig`);
after an idealised move they are the move's direction ``(mx, my) / |(mx, my)|``, which is
what the new heading ``atan2(my, mx)`` stands for, computed without the round trip through
the angle (so they may differ from ``cos(atan2(my, mx))`` in the last bit). Measured: this
and the fused step cut the world step by a fifth; libm's sin and cos mispredict branches on
fresh data.
"""

from __future__ import annotations

import math

import numpy as np

from physrover.compiled import jit


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
def heading_trig(headings, cos_h, sin_h):
    """``cos_h, sin_h = cos(headings), sin(headings)`` for (E, R) float64 arrays, in place."""
    n_teams, n_rovers = headings.shape
    for e in range(n_teams):
        for i in range(n_rovers):
            cos_h[e, i] = math.cos(headings[e, i])
            sin_h[e, i] = math.sin(headings[e, i])


@jit
def _move(cos_h, sin_h, heading, fwd, left):
    """One rover's idealised move: the world-frame displacement (mx, my) of the command
    (fwd, left) and the new heading (its direction; the old one for a zero command)."""
    mx = cos_h * fwd - sin_h * left
    my = sin_h * fwd + cos_h * left
    new_heading = math.atan2(my, mx) if (fwd != 0.0 or left != 0.0) else heading
    return mx, my, new_heading


@jit
def _observe_team(
    e,
    rover_positions,  # (E, R, 2) float64
    cos_h,  # (E, R) float64
    sin_h,  # (E, R) float64
    poi_positions,  # (E, K, 2) float64
    poi_values,  # (E, K) float64
    d_min_sq,
    d_cap_sq,
    n_req,
    t,
    captured,  # (E, K) bool, updated
    captured_without,  # (E, R, K) bool, updated
    capture_step,  # (E, K) int64, updated
    score,  # (E,) float64, written
    obs,  # (E, R, 8) float32, written
    counts,  # (E, K) int64, written: rovers within d_cap of each POI
    near,  # (R, K) int64 scratch
    acc,  # (8,) float64 scratch
):
    """Sense and score step ``t`` of team ``e`` (see :func:`observe_and_score`)."""
    n_rovers = cos_h.shape[1]
    n_pois = poi_positions.shape[1]
    count = counts[e]
    count[:] = 0
    for i in range(n_rovers):
        c = cos_h[e, i]
        s = sin_h[e, i]
        xi = rover_positions[e, i, 0]
        yi = rover_positions[e, i, 1]
        acc[:] = 0.0  # by quadrant: Eq. 15 in 0-3, Eq. 16 in 4-7
        for j in range(n_rovers):  # the other rovers, numerator 1
            if j == i:
                continue
            dx = rover_positions[e, j, 0] - xi
            dy = rover_positions[e, j, 1] - yi
            dist_sq = max(dx * dx + dy * dy, d_min_sq)  # Eq. 14
            # An indexed add, not one select per quadrant: with real (changing) data the
            # compiler's branches for selects mispredict and cost more than the whole sum.
            acc[quadrant(c * dx + s * dy, c * dy - s * dx)] += 1.0 / dist_sq
        for k in range(n_pois):  # the POIs, numerator V_k
            dx = poi_positions[e, k, 0] - xi
            dy = poi_positions[e, k, 1] - yi
            dist_sq = max(dx * dx + dy * dy, d_min_sq)
            acc[4 + quadrant(c * dx + s * dy, c * dy - s * dx)] += poi_values[e, k] / dist_sq
            inside = np.int64(dist_sq <= d_cap_sq)  # Eq. 13
            near[i, k] = inside
            count[k] += inside
        for q in range(8):
            obs[e, i, q] = acc[q]
    total = 0.0
    for k in range(n_pois):
        if count[k] >= n_req:  # Eq. 12
            if not captured[e, k]:
                capture_step[e, k] = t
                captured[e, k] = True
        for i in range(n_rovers):  # Eq. 12 without rover i
            if count[k] - near[i, k] >= n_req:
                captured_without[e, i, k] = True
        if captured[e, k]:  # Eq. 11
            total += poi_values[e, k]
    score[e] = total


@jit
def observe_and_score(
    rover_positions,  # (E, R, 2) float64
    cos_h,  # (E, R) float64: cos of the headings
    sin_h,  # (E, R) float64: sin of the headings
    poi_positions,  # (E, K, 2) float64
    poi_values,  # (E, K) float64
    d_min,
    d_cap,
    n_req,
    t,
    captured,  # (E, K) bool, updated
    captured_without,  # (E, R, K) bool, updated
    capture_step,  # (E, K) int64, updated
    score,  # (E,) float64, written
    poi_counts,  # (E, K) int64, written: rovers within d_cap of each POI at this step
    obs,  # (E, R, 8) float32, written
):
    """Sense (Eqs. 15-16) and score (Eqs. 11-13) step ``t`` for every team, in place.

    ``captured``, ``captured_without``, ``capture_step`` and ``score`` (G so far) are the
    arrays of a :class:`~physrover.domain.scoring.ScoreKeeper`, advanced by one step. Each
    sensor channel adds its terms object by object (rovers by index, then POIs).
    """
    n_teams, n_rovers = cos_h.shape
    n_pois = poi_positions.shape[1]
    near = np.empty((n_rovers, n_pois), np.int64)
    acc = np.empty(8)
    for e in range(n_teams):
        _observe_team(
            e, rover_positions, cos_h, sin_h, poi_positions, poi_values, d_min * d_min,
            d_cap * d_cap, n_req, t, captured, captured_without, capture_step, score, obs,
            poi_counts, near, acc,
        )  # fmt: skip


@jit
def ideal_step(
    commands,  # (E, R, 2) float32 or float64: the actions as given
    positions,  # (E, R, 2) float64: before the step
    headings,  # (E, R) float64: before the step
    cos_h,  # (E, R) float64: cos(headings), updated to the new headings
    sin_h,  # (E, R) float64: sin(headings), updated to the new headings
    actions,  # (E, R, 2) float32: written with the clipped actions
    new_positions,  # (E, R, 2) float64, written
    new_headings,  # (E, R) float64, written
    poi_positions,
    poi_values,
    d_min,
    d_cap,
    n_req,
    t,
    captured,
    captured_without,
    capture_step,
    score,
    poi_counts,
    obs,  # (E, R, 8) float32, written with the new observations
    obs_record,  # (E, R, 8) float32, written with them too (may be ``obs`` itself)
):
    """One idealised world step of every team: ``RoverWorld.step`` under ``motion="ideal"``.

    Returns False, having changed nothing, if a command is NaN. Otherwise clips the commands
    to [-1, 1] (in float64, as ``np.clip``), records them in ``actions``, moves every rover
    (:func:`_move`), and senses and scores the new state as :func:`observe_and_score` (the
    arguments of the same names are the same), team by team while its data is in cache.
    """
    n_teams, n_rovers = headings.shape
    n_pois = poi_positions.shape[1]
    for e in range(n_teams):
        for i in range(n_rovers):
            if math.isnan(commands[e, i, 0]) or math.isnan(commands[e, i, 1]):
                return False
    near = np.empty((n_rovers, n_pois), np.int64)
    acc = np.empty(8)
    for e in range(n_teams):
        for i in range(n_rovers):
            fwd = min(max(np.float64(commands[e, i, 0]), -1.0), 1.0)
            left = min(max(np.float64(commands[e, i, 1]), -1.0), 1.0)
            actions[e, i, 0] = fwd
            actions[e, i, 1] = left
            mx, my, heading = _move(cos_h[e, i], sin_h[e, i], headings[e, i], fwd, left)
            new_positions[e, i, 0] = positions[e, i, 0] + mx
            new_positions[e, i, 1] = positions[e, i, 1] + my
            new_headings[e, i] = heading
            # The new heading's cosine and sine: the move's direction (the module docstring).
            norm = math.sqrt(mx * mx + my * my)
            if norm > 1e-100:
                cos_h[e, i] = mx / norm
                sin_h[e, i] = my / norm
            elif fwd != 0.0 or left != 0.0:  # a move so small that its square underflows
                cos_h[e, i] = math.cos(heading)
                sin_h[e, i] = math.sin(heading)
        _observe_team(
            e, new_positions, cos_h, sin_h, poi_positions, poi_values, d_min * d_min,
            d_cap * d_cap, n_req, t, captured, captured_without, capture_step, score, obs,
            poi_counts, near, acc,
        )  # fmt: skip
        for i in range(n_rovers):
            for c in range(8):
                obs_record[e, i, c] = obs[e, i, c]
    return True
