"""Compiled kernels of the world step: the one implementation of Eqs. 11-16 and of the
idealised motion (Section 4.1.2). Each takes the world's state, a
:class:`~physrover.domain.state.WorldState`, and writes only its own part of it.

- :func:`sense`: the sector densities of Eqs. 14-16 (:mod:`physrover.domain.sensors`;
  its kernels are in :mod:`physrover.domain.sense_kernels`, re-exported here);
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

from physrover.core.compiled import jit, jit_inline
from physrover.domain.sense_kernels import (  # noqa: F401 (the sensor's kernels, re-exported)
    PAD,
    quadrant,
    sector,
    sense,
    sense_scratch,
    sense_team,
)
from physrover.domain.state import WorldState


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
def score_team(e, state, d_cap_sq, n_req, t, rules=None):
    """Score step ``t`` of team ``e`` (Eqs. 11-13 and D's counterfactual captures) in
    ``state``'s scoring arrays; ``n_req`` (K,) int64 is each POI's coupling; ``rules`` a
    :class:`~physrover.domain.poi_rules.PoiRules` or None (the paper's POIs: the rules'
    branches are compiled away).

    Eq. 13 uses the bounded distance of Eq. 14, ``max(d, d_min) <= d_cap``, which is
    ``d <= d_cap`` since the config keeps ``d_min <= d_cap`` (and every capture radius
    ``>= d_min``).
    """
    positions, poi_positions = state.rover_positions, state.poi_positions
    n_rovers = positions.shape[1]
    n_pois = poi_positions.shape[1]
    count = state.poi_counts[e]
    near = state.in_range[t, e]
    captured, captured_without = state.captured, state.captured_without
    for k in range(n_pois):
        radius_sq = d_cap_sq
        if rules is not None:
            radius_sq = rules.capture_radius_sq[k]
        px = poi_positions[e, k, 0]
        py = poi_positions[e, k, 1]
        n = 0
        for i in range(n_rovers):
            dx = px - positions[e, i, 0]
            dy = py - positions[e, i, 1]
            inside = dx * dx + dy * dy <= radius_sq  # Eq. 13
            if rules is not None:
                inside = inside and rules.counts_for[k, i]
            near[i, k] = inside
            n += np.int64(inside)
        count[k] = n
    total = 0.0
    for k in range(n_pois):
        if rules is not None:
            _score_rules(e, k, near, state, rules, n_req, t)
        else:
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


@jit_inline
def predecessors_before(after, k, first_steps, t):
    """Whether every POI j with ``after[k, j]`` was first captured (``first_steps[j]``, -1:
    never) at a step before ``t``."""
    for j in range(after.shape[1]):
        if after[k, j] and (first_steps[j] < 0 or first_steps[j] >= t):
            return False
    return True


@jit_inline
def _score_rules(e, k, near, state, rules, n_req, t):
    """Eq. 12 for POI k of team e at step t under ``rules`` (:mod:`physrover.domain.poi_rules`),
    for the team and for each counterfactual without rover i; the counts are this step's.

    Leaving an agent out never raises a count, so no counterfactual meets a coupling that the
    team misses, and leaving out an agent not in range changes nothing: the coupling is
    counted again only without each agent in range (O(R) a POI, not O(R^2)). ``near`` is
    ``state.in_range[t, e]``, the team's view, passed in rather than made again per POI."""
    if rules.final_only[k] and t != rules.t_final:
        return
    if not coupling_met(k, near, rules, n_req, -1):
        return
    if not state.captured[e, k] and predecessors_before(rules.after, k, state.capture_step[e], t):
        state.capture_step[e, k] = t
        state.captured[e, k] = True
    for i in range(near.shape[0]):
        if state.captured_without[e, i, k]:
            continue
        if near[i, k] and not coupling_met(k, near, rules, n_req, i):
            continue
        if predecessors_before(rules.after, k, rules.step_without[e, i], t):
            state.captured_without[e, i, k] = True
            rules.step_without[e, i, k] = t


@jit_inline
def coupling_met(k, near, rules, n_req, without):
    """Eq. 12 for POI k from one step's in-range agents ``near`` (R, K) bool, agent
    ``without`` left out (-1: none): ``n_req[k]`` of them, or for a typed POI
    (``require``) at least ``require[k, c]`` of each class c."""
    typed = rules.typed[k]
    for c in range(rules.require.shape[1] if typed else 1):
        need = rules.require[k, c] if typed else n_req[k]
        n = 0
        for i in range(near.shape[0]):
            if i != without and near[i, k] and (not typed or rules.agent_class[i] == c):
                n += 1
        if n < need:
            return False
    return True


@jit
def score(state, d_cap, n_req, t, rules=None):
    """Score step ``t`` (0 after reset, then 1, 2, ...) of every team in ``state``: the POIs'
    rover counts and which rovers are in range (``in_range[t]``), captures (Eqs. 12-13)
    under each POI's coupling ``n_req`` (K,) int64, G so far (Eq. 11) and the captures
    without each rover (the counterfactual of D, Eq. 1); ``rules``: :func:`score_team`'s."""
    for e in range(state.cos_h.shape[0]):
        score_team(e, state, d_cap * d_cap, n_req, t, rules)


@jit
def _clip(x):
    return min(max(np.float64(x), -1.0), 1.0)


@jit
def move_team(e, commands, state, actions, headings=True, roles=None):
    """Move the rovers of team ``e`` by their clipped ``commands`` (recorded in ``actions``):
    positions, headings (NaN unless ``headings``, see :func:`_move`) and their cosines and
    sines in ``state``. ``roles``: agent classes' gates, speeds, frames and bounds
    (:class:`~physrover.domain.roles.Roles`; None, the paper's rovers, compiles them away)."""
    positions, angles = state.rover_positions, state.rover_headings
    cos_h, sin_h = state.cos_h, state.sin_h
    if roles is not None:
        free = _gate_free(e, positions, roles)
    for i in range(angles.shape[1]):
        fwd = _clip(commands[e, i, 0])
        left = _clip(commands[e, i, 1])
        actions[e, i, 0] = fwd
        actions[e, i, 1] = left
        if roles is not None:
            scale = roles.speed[i] if free[i] else 0.0
            fwd, left = fwd * scale, left * scale
            if roles.world_frame[i]:  # (x, y) as given: the turn to cos 1, sin 0 is none
                mx, my, heading = _move(1.0, 0.0, angles[e, i], fwd, left, headings)
            else:
                mx, my, heading = _move(cos_h[e, i], sin_h[e, i], angles[e, i], fwd, left,
                                        headings)  # fmt: skip
            x_min, x_max = roles.bounds[i, 0], roles.bounds[i, 1]
            y_min, y_max = roles.bounds[i, 2], roles.bounds[i, 3]
            positions[e, i, 0] = min(max(positions[e, i, 0] + mx, x_min), x_max)
            positions[e, i, 1] = min(max(positions[e, i, 1] + my, y_min), y_max)
        else:
            mx, my, heading = _move(cos_h[e, i], sin_h[e, i], angles[e, i], fwd, left,
                                    headings)  # fmt: skip
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
def _gate_free(e, positions, roles):
    """(R,) bool: whether each agent of team e may move this step, from the positions
    before anyone moves (:mod:`physrover.domain.roles`, step 1)."""
    n = positions.shape[1]
    free = np.ones(n, dtype=np.bool_)
    for i in range(n):
        if not roles.gate[i].any():
            continue
        free[i] = False
        for j in range(n):
            if j != i and roles.gate[i, roles.agent_class[j]]:
                dx = positions[e, j, 0] - positions[e, i, 0]
                dy = positions[e, j, 1] - positions[e, i, 1]
                if dx * dx + dy * dy <= roles.gate_radius_sq[i]:
                    free[i] = True
                    break
    return free


@jit
def _any_nan(commands):
    for e in range(commands.shape[0]):
        for i in range(commands.shape[1]):
            if math.isnan(commands[e, i, 0]) or math.isnan(commands[e, i, 1]):
                return True
    return False


@jit
def move(commands, state, actions, roles=None):
    """The idealised motion of every rover under (E, R, 2) ``commands`` (float32 or float64,
    as given): returns False, having changed nothing, if a command is NaN; otherwise clips
    them to [-1, 1] (in float64, as ``np.clip``), records them in ``actions`` (E, R, 2) and
    moves the rovers in ``state`` (:func:`_move`; ``roles``: :func:`move_team`'s)."""
    if _any_nan(commands):
        return False
    for e in range(commands.shape[0]):
        move_team(e, commands, state, actions, True, roles)
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
