"""Compiled kernels of the world step: the one implementation of Eqs. 11-16 and of the
idealised motion (Section 4.1.2). Each takes the world's state, a
:class:`~physrover.domain.state.WorldState`, and writes only its own part of it.

- :func:`sense`: the sector densities of Eqs. 14-16 (:mod:`physrover.domain.sensors`);
- :func:`score`: one step's captures (Eqs. 12-13), G so far (Eq. 11) and the
  counterfactual captures of D (Eq. 1), :mod:`physrover.domain.scoring`;
- :func:`move`: the idealised motion of every rover;
- :func:`ideal_step`: the three composed into a whole idealised world step in one call
  (check and clip the actions, move, sense, score, record), team by team while its data is
  in cache, so that a step costs one call instead of a dozen.

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

from physrover.core.compiled import jit
from physrover.domain.state import WorldState


@jit
def quadrant(forward: float, left: float) -> int:
    """Quadrant of an offset (forward, left) in the rover's frame (the convention of
    :mod:`physrover.domain.sensors`).

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
def _move(cos_h, sin_h, heading, fwd, left, headings):
    """One rover's idealised move: the world-frame displacement (mx, my) of the command
    (fwd, left) and the new heading (its direction; the old one for a zero command), or NaN
    unless ``headings`` (nothing under idealised motion reads the angle: it moves and senses
    with the heading's cosine and sine, and libm's atan2 is a sixth of a world step)."""
    mx = cos_h * fwd - sin_h * left
    my = sin_h * fwd + cos_h * left
    if not headings:
        return mx, my, np.nan
    new_heading = math.atan2(my, mx) if (fwd != 0.0 or left != 0.0) else heading
    return mx, my, new_heading


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


PAD = 16
"""The quadrant sensor's loops over a team's rovers run over a multiple of this many lanes
(LLVM vectorises them 4 doubles x 4 interleaved; a remainder would run scalar)."""


@jit
def sense_scratch(n_rovers, sectors):
    """Scratch of :func:`sense_team`: (4 + 2 n_sectors, width) float64, rows the rovers' x, y,
    cos and sin (padded lanes: a rover at the origin facing +x, never read back) and the
    channels' sums, ``width`` >= R a multiple of :data:`PAD` (and >= 2 n_sectors)."""
    n_sectors = len(sectors)
    width = max(-(-n_rovers // PAD) * PAD, 2 * n_sectors)
    scratch = np.zeros((4 + 2 * n_sectors, width))
    scratch[2, :] = 1.0
    return scratch


@jit
def _sense_quadrants(e, state, d_min_sq, radius_sq, obs, scratch):
    """Eqs. 14-16 in four quadrants for the rovers of team ``e``, vectorised over the
    observing rovers: for each object (rovers by index, then POIs) every rover's four
    channel sums get the object's term or +0.0 (the same sums, in the same order, as adding
    it to its one channel; an unseen object or the rover itself adds +0.0 everywhere)."""
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    poi_positions, poi_values = state.poi_positions, state.poi_values
    n_rovers = cos_h.shape[1]
    n_pois = poi_positions.shape[1]
    width = scratch.shape[1]
    px, py, cs, sn = scratch[0], scratch[1], scratch[2], scratch[3]
    r0, r1, r2, r3 = scratch[4], scratch[5], scratch[6], scratch[7]  # Eq. 15 by quadrant
    p0, p1, p2, p3 = scratch[8], scratch[9], scratch[10], scratch[11]  # Eq. 16 by quadrant
    for i in range(n_rovers):
        px[i] = positions[e, i, 0]
        py[i] = positions[e, i, 1]
        cs[i] = cos_h[e, i]
        sn[i] = sin_h[e, i]
    for i in range(width):
        r0[i] = r1[i] = r2[i] = r3[i] = p0[i] = p1[i] = p2[i] = p3[i] = 0.0
    # The two loops below differ only in the numerator, the self lane and the sums they add
    # to; one helper called for both halved their speed (37 -> 69 us per 50-team step: the
    # call kept LLVM from vectorising), so they stay written out.
    for j in range(n_rovers):  # the other rovers, numerator 1
        xj = positions[e, j, 0]
        yj = positions[e, j, 1]
        for i in range(width):
            dx = xj - px[i]
            dy = yj - py[i]
            dist_sq = dx * dx + dy * dy
            w = 1.0 / max(dist_sq, d_min_sq)  # Eq. 14
            if radius_sq is not None:
                w = w if dist_sq <= radius_sq else 0.0
            w = w if i != j else 0.0
            q = quadrant(cs[i] * dx + sn[i] * dy, cs[i] * dy - sn[i] * dx)
            r0[i] += w if q == 0 else 0.0
            r1[i] += w if q == 1 else 0.0
            r2[i] += w if q == 2 else 0.0
            r3[i] += w if q == 3 else 0.0
    for k in range(n_pois):  # the POIs, numerator V_k
        xk = poi_positions[e, k, 0]
        yk = poi_positions[e, k, 1]
        value = poi_values[e, k]
        for i in range(width):
            dx = xk - px[i]
            dy = yk - py[i]
            dist_sq = dx * dx + dy * dy
            w = value / max(dist_sq, d_min_sq)
            if radius_sq is not None:
                w = w if dist_sq <= radius_sq else 0.0
            q = quadrant(cs[i] * dx + sn[i] * dy, cs[i] * dy - sn[i] * dx)
            p0[i] += w if q == 0 else 0.0
            p1[i] += w if q == 1 else 0.0
            p2[i] += w if q == 2 else 0.0
            p3[i] += w if q == 3 else 0.0
    for i in range(n_rovers):
        obs[e, i, 0] = r0[i]
        obs[e, i, 1] = r1[i]
        obs[e, i, 2] = r2[i]
        obs[e, i, 3] = r3[i]
        obs[e, i, 4] = p0[i]
        obs[e, i, 5] = p1[i]
        obs[e, i, 6] = p2[i]
        obs[e, i, 7] = p3[i]


@jit
def sense_team(e, state, d_min_sq, sectors, radius_sq, obs, scratch):
    """Eqs. 14-16 for the rovers of team ``e`` in ``len(sectors)`` sectors: ``obs[e]``
    (R, 2 n_sectors) from ``state``, objects farther than ``sqrt(radius_sq)`` unseen (None:
    none); ``scratch`` from :func:`sense_scratch`. Each channel adds its terms object by
    object (rovers by index, then POIs).

    ``sectors`` is a tuple of n zeros (:func:`physrover.core.compiled.dims`) and ``radius_sq``
    may be None: the compiler then knows the sector count and whether there is a radius,
    and compiles the paper's sensor (4 sectors, no radius) as if it were written alone.
    Four sectors take the vectorised :func:`_sense_quadrants`; others the loop below.
    """
    n_sectors = len(sectors)
    if n_sectors == 4:
        _sense_quadrants(e, state, d_min_sq, radius_sq, obs, scratch)
        return
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    poi_positions, poi_values = state.poi_positions, state.poi_values
    n_rovers = cos_h.shape[1]
    n_pois = poi_positions.shape[1]
    acc = scratch[4]  # by sector: Eq. 15 in 0 .. n-1, Eq. 16 in n .. 2n-1
    for i in range(n_rovers):
        c = cos_h[e, i]
        s = sin_h[e, i]
        xi = positions[e, i, 0]
        yi = positions[e, i, 1]
        acc[:] = 0.0
        for j in range(n_rovers):  # the other rovers, numerator 1
            if j == i:
                continue
            dx = positions[e, j, 0] - xi
            dy = positions[e, j, 1] - yi
            dist_sq = dx * dx + dy * dy
            if radius_sq is not None and dist_sq > radius_sq:  # beyond the radius
                continue
            dist_sq = max(dist_sq, d_min_sq)  # Eq. 14
            acc[sector(c * dx + s * dy, c * dy - s * dx, n_sectors)] += 1.0 / dist_sq
        for k in range(n_pois):  # the POIs, numerator V_k
            dx = poi_positions[e, k, 0] - xi
            dy = poi_positions[e, k, 1] - yi
            dist_sq = dx * dx + dy * dy
            if radius_sq is not None and dist_sq > radius_sq:
                continue
            dist_sq = max(dist_sq, d_min_sq)
            q = n_sectors + sector(c * dx + s * dy, c * dy - s * dx, n_sectors)
            acc[q] += poi_values[e, k] / dist_sq
        for q in range(2 * n_sectors):
            obs[e, i, q] = acc[q]


@jit
def score_team(e, state, d_cap_sq, n_req, t):
    """Score step ``t`` of team ``e`` (Eqs. 11-13 and D's counterfactual captures) in
    ``state``'s scoring arrays; ``n_req`` (K,) int64 is each POI's coupling.

    Eq. 13 uses the bounded distance of Eq. 14, ``max(d, d_min) <= d_cap``, which is
    ``d <= d_cap`` since the config keeps ``d_min <= d_cap``.
    """
    positions, poi_positions = state.rover_positions, state.poi_positions
    n_rovers = positions.shape[1]
    n_pois = poi_positions.shape[1]
    count = state.poi_counts[e]
    near = state.in_range[t, e]
    captured, captured_without = state.captured, state.captured_without
    for k in range(n_pois):
        px = poi_positions[e, k, 0]
        py = poi_positions[e, k, 1]
        n = 0
        for i in range(n_rovers):
            dx = px - positions[e, i, 0]
            dy = py - positions[e, i, 1]
            inside = dx * dx + dy * dy <= d_cap_sq  # Eq. 13
            near[i, k] = inside
            n += np.int64(inside)
        count[k] = n
    total = 0.0
    for k in range(n_pois):
        if count[k] >= n_req[k]:  # Eq. 12
            if not captured[e, k]:
                state.capture_step[e, k] = t
                captured[e, k] = True
        for i in range(n_rovers):  # Eq. 12 without rover i
            if count[k] - np.int64(near[i, k]) >= n_req[k]:
                captured_without[e, i, k] = True
        if captured[e, k]:  # Eq. 11
            total += state.poi_values[e, k]
    state.score[e] = total


@jit
def sense(state, d_min, sectors, radius_sq, obs):
    """The density sensor (Eqs. 14-16) of every rover of every team in ``len(sectors)``
    sectors (a tuple of zeros, :func:`physrover.core.compiled.dims`), blind beyond
    ``sqrt(radius_sq)`` world units (None: sees everything): ``obs`` (E, R, 2 n_sectors)
    float32, written."""
    scratch = sense_scratch(state.cos_h.shape[1], sectors)
    for e in range(state.cos_h.shape[0]):
        sense_team(e, state, d_min * d_min, sectors, radius_sq, obs, scratch)


@jit
def score(state, d_cap, n_req, t):
    """Score step ``t`` (0 after reset, then 1, 2, ...) of every team in ``state``: the POIs'
    rover counts and which rovers are in range (``in_range[t]``), captures (Eqs. 12-13)
    under each POI's coupling ``n_req`` (K,) int64, G so far (Eq. 11) and the captures
    without each rover (the counterfactual of D, Eq. 1)."""
    for e in range(state.cos_h.shape[0]):
        score_team(e, state, d_cap * d_cap, n_req, t)


@jit
def _clip(x):
    return min(max(np.float64(x), -1.0), 1.0)


@jit
def move_team(e, commands, state, actions, headings=True):
    """Move the rovers of team ``e`` by their clipped ``commands`` (recorded in ``actions``):
    positions, headings (NaN unless ``headings``, see :func:`_move`) and their cosines and
    sines in ``state``."""
    positions, angles = state.rover_positions, state.rover_headings
    cos_h, sin_h = state.cos_h, state.sin_h
    for i in range(angles.shape[1]):
        fwd = _clip(commands[e, i, 0])
        left = _clip(commands[e, i, 1])
        actions[e, i, 0] = fwd
        actions[e, i, 1] = left
        mx, my, heading = _move(cos_h[e, i], sin_h[e, i], angles[e, i], fwd, left, headings)
        positions[e, i, 0] += mx
        positions[e, i, 1] += my
        angles[e, i] = heading
        # The new heading's cosine and sine: the move's direction (the module docstring).
        norm = math.sqrt(mx * mx + my * my)
        if norm > 1e-100:
            cos_h[e, i] = mx / norm
            sin_h[e, i] = my / norm
        elif fwd != 0.0 or left != 0.0:  # a move so small that its square underflows
            heading = math.atan2(my, mx)
            cos_h[e, i] = math.cos(heading)
            sin_h[e, i] = math.sin(heading)


@jit
def _any_nan(commands):
    for e in range(commands.shape[0]):
        for i in range(commands.shape[1]):
            if math.isnan(commands[e, i, 0]) or math.isnan(commands[e, i, 1]):
                return True
    return False


@jit
def move(commands, state, actions):
    """The idealised motion of every rover under (E, R, 2) ``commands`` (float32 or float64,
    as given): returns False, having changed nothing, if a command is NaN; otherwise clips
    them to [-1, 1] (in float64, as ``np.clip``), records them in ``actions`` (E, R, 2) and
    moves the rovers in ``state`` (:func:`_move`)."""
    if _any_nan(commands):
        return False
    for e in range(commands.shape[0]):
        move_team(e, commands, state, actions)
    return True


@jit
def ideal_step(commands, state, sensing, d_cap, n_req, t, scored, actions, positions, headings,
               obs):  # fmt: skip
    """One idealised world step of every team: :func:`move`, :func:`sense` (``sensing`` is
    its ``(d_min, sectors, radius_sq)``) and (if ``scored``) :func:`score` of step ``t``
    composed team by team, with the records: ``actions`` (E, R, 2) float32 the clipped
    commands, ``positions`` (E, R, 2) and ``headings`` (E, R) copies of the new state,
    ``obs`` (E, R, 2 n_sectors) float32 the new observations. Returns False, having changed
    nothing, if a command is NaN.
    """
    if _any_nan(commands):
        return False
    n_teams, n_rovers = state.cos_h.shape
    d_min, sectors, radius_sq = sensing
    scratch = sense_scratch(n_rovers, sectors)
    for e in range(n_teams):
        move_team(e, commands, state, actions)
        sense_team(e, state, d_min * d_min, sectors, radius_sq, obs, scratch)
        if scored:
            score_team(e, state, d_cap * d_cap, n_req, t)
        for i in range(n_rovers):
            positions[e, i, 0] = state.rover_positions[e, i, 0]
            positions[e, i, 1] = state.rover_positions[e, i, 1]
            headings[e, i] = state.rover_headings[e, i]
    return True


@jit
def ideal_step_flat(commands, d_min, sectors, radius_sq, d_cap, n_req, t, scored, actions,
                    positions, headings, obs, *state):  # fmt: skip
    """:func:`ideal_step` with the sensing parameters and the state's arrays passed one by
    one (``*state`` in :class:`~physrover.domain.state.WorldState` order): the world's hot
    path. numba types plain arrays at the call in C but a tuple in Python, which cost ~2 us
    per step (4% of a 50-team step); the kernel rebuilds the tuple inside, for free."""
    return ideal_step(commands, WorldState(*state), (d_min, sectors, radius_sq), d_cap, n_req,
                      t, scored, actions, positions, headings, obs)  # fmt: skip


class Fused:
    """Mixin of the parts compiled into :func:`ideal_step` (the idealised motion and the
    quadrant sensor), declared with ``fused=True``; ``fused`` is False for their subclasses,
    whose own methods the world must call instead of the fused kernel."""

    fused = False

    def __init_subclass__(cls, fused: bool = False, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.fused = fused
