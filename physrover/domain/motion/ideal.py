"""The paper's idealised kinematics (Section 4.1.2), compiled: the command (forward, left)
in the rover's frame is the step's displacement, and the rover turns to face it.

This module is the one implementation of the idealised move (:func:`ideal_move`), of the
command's check and clip (:func:`commands_ok`, :func:`clip`); a class's command and frame
come from :func:`physrover.domain.agents.roles.class_command`. The physical model's setpoint
(:func:`physrover.domain.motion.integrator.setpoints`) is the same move.

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
from physrover.domain.agents.failures import alive
from physrover.domain.agents.roles import class_command, gate_free, pick_moves


@jit
def heading_trig(headings, cos_h, sin_h):
    """``cos_h, sin_h = cos(headings), sin(headings)`` for (E, R) float64 arrays, in place."""
    n_teams, n_rovers = headings.shape
    for e in range(n_teams):
        for i in range(n_rovers):
            cos_h[e, i] = math.cos(headings[e, i])
            sin_h[e, i] = math.sin(headings[e, i])


@jit
def ideal_move(cos_h, sin_h, heading, fwd, left, headings):
    """One rover's idealised move: the world-frame displacement (mx, my) of the command
    (fwd, left) in the frame of the heading whose cosine and sine are given, and the new
    heading (its direction; the old one for a zero command), or NaN unless ``headings``
    (nothing under idealised motion reads the angle: it moves and senses with the heading's
    cosine and sine, and libm's atan2 is a sixth of a world step)."""
    mx = cos_h * fwd - sin_h * left
    my = sin_h * fwd + cos_h * left
    if not headings:
        return mx, my, np.nan
    new_heading = math.atan2(my, mx) if (fwd != 0.0 or left != 0.0) else heading
    return mx, my, new_heading


@jit
def clip(x):
    """A command component clipped to [-1, 1], in float64 (as ``np.clip``)."""
    return min(max(np.float64(x), -1.0), 1.0)


@jit
def commands_ok(commands):
    """Whether none of one team's (R, 2) commands is NaN (the step's check)."""
    for i in range(commands.shape[0]):
        if math.isnan(commands[i, 0]) or math.isnan(commands[i, 1]):
            return False
    return True


@jit
def all_commands_ok(commands):
    """:func:`commands_ok` for every team of (E, R, 2) ``commands``."""
    for e in range(commands.shape[0]):
        if not commands_ok(commands[e]):
            return False
    return True


@jit
def move_team(e, commands, state, actions, headings, roles, free, failures=None, t=0):
    """Move the rovers of team ``e`` by their clipped ``commands`` (E, R, 2) (recorded in
    ``actions`` (E, R, 2)): positions, headings (NaN unless ``headings``, see
    :func:`ideal_move`) and their cosines and sines in ``state``. ``roles``: the agent
    classes' rule (:class:`~physrover.domain.agents.roles.Roles`; None, the paper's
    rovers, compiles it away), ``free`` its (R,) bool scratch. ``failures``
    (:class:`~physrover.domain.agents.failures.Failures`; None compiles it away): an agent
    not alive at state ``t``, the state this move leads to, stays put, its command 0."""
    positions, angles = state.rover_positions, state.rover_headings
    cos_h, sin_h = state.cos_h, state.sin_h
    if roles is not None:
        gate_free(e, positions, roles, free)
        pick_moves(e, positions, commands, roles)
    for i in range(angles.shape[1]):
        fwd = clip(commands[e, i, 0])
        left = clip(commands[e, i, 1])
        if not alive(failures, e, t, i):
            fwd = left = 0.0
            if roles is not None:
                free[i] = False
        actions[e, i, 0] = fwd
        actions[e, i, 1] = left
        if roles is not None:
            fwd, left, c, s = class_command(i, fwd, left, free, roles, cos_h[e, i], sin_h[e, i])
            mx, my, heading = ideal_move(c, s, angles[e, i], fwd, left, headings)
            x_min, x_max = roles.bounds[i, 0], roles.bounds[i, 1]  # step 4: the class's box
            y_min, y_max = roles.bounds[i, 2], roles.bounds[i, 3]
            positions[e, i, 0] = min(max(positions[e, i, 0] + mx, x_min), x_max)
            positions[e, i, 1] = min(max(positions[e, i, 1] + my, y_min), y_max)
        else:
            mx, my, heading = ideal_move(cos_h[e, i], sin_h[e, i], angles[e, i], fwd, left,
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
def clip_teams(commands, out, record):
    """The commands of every team clipped to [-1, 1] into ``out`` (E, R, 2) float64 (what a
    motion model stepped outside the compiled step takes) and ``record`` (E, R, 2) float32
    (the trajectory); returns False, having written nothing, if a command is NaN."""
    if not all_commands_ok(commands):
        return False
    for e in range(commands.shape[0]):
        for i in range(commands.shape[1]):
            for a in range(2):
                out[e, i, a] = clip(commands[e, i, a])
                record[e, i, a] = out[e, i, a]
    return True


__all__ = ["all_commands_ok", "clip", "clip_teams", "commands_ok", "heading_trig",
           "ideal_move", "move_team"]  # fmt: skip
