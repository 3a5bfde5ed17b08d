"""A class's motion rule, compiled: the per-agent constants that both motion models read.

:class:`Roles` holds each agent's class constants as arrays (agents in team order), and
the motion kernels take it as their ``roles`` argument (None, the paper's rovers, compiles
it away). With roles, agent i's command ``a``, already clipped to [-1, 1], becomes its move:

1. *gate* (:func:`gate_free`): if its class names ``moves_with`` classes and no agent of
   them is within ``gate_radius`` of it at the start of the step (every agent's position
   before anyone moves: the scan its action was computed from), ``a = 0``;
2. *speed*: ``a = max_speed * a`` (:func:`class_command`);
3. *frame*: a body-frame agent moves as the paper's rover (``a`` in its own frame); a
   world-frame one by ``a`` itself; either way the heading turns to the move's direction
   (:func:`class_command`, then :func:`physrover.domain.motion.ideal.ideal_move`). A
   *picking* agent (``action = "pick"`` or ``"follow"``, the lab's ``pick_uav`` action and
   ``follow`` policy, ``ccea_lib.py`` ``evaluateTeamStatic``) moves instead by
   ``clip(p_j - p_i, -max_speed, max_speed)`` per component towards one of the U agents
   of its ``picks`` classes (in team order), judged on the positions before anyone moves
   (:func:`pick_moves`), or stays: under ``"pick"`` its command's first component,
   clipped to [-1, 1], picks target ``j = floor((a + 1) / 2 (U + 1))`` (U + 1 equal bins;
   the last, and ``a = 1``, is "stay", the lab's extra output); under ``"follow"`` j is
   the nearest within its sensor radius (ties: the lower index; none: stay); the gate of
   step 1 still applies;
4. *bounds*: the new position is clamped to its class's box (+-inf: none; idealised motion
   only, the config refuses bounds under physics).

Under physical motion steps 1-3 make the body's setpoint (the idealised move, which the
controller then tracks with finite force).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from physrover.core.compiled import jit_inline
from physrover.domain.agents.classes import (
    agent_classes,
    class_names,
    gate_radius,
    pick_count,
    sensor_radius,
)

PICK_MODES = ("", "pick", "follow")
"""``Roles.pick_mode`` 1 and 2: the picking actions."""


class Roles(NamedTuple):
    """Per-agent constants of R agents in C classes (module docstring)."""

    agent_class: np.ndarray
    """(R,) int64: each agent's class, in ``[[agents]]`` order."""
    speed: np.ndarray
    """(R,) float64: the class's ``max_speed``."""
    world_frame: np.ndarray
    """(R,) bool: the class's action is ``"world"``."""
    bounds: np.ndarray
    """(R, 4) float64: x_min, x_max, y_min, y_max (+-inf: unbounded)."""
    gate: np.ndarray
    """(R, M) int64: the agents one of which must be near for agent i to move, the first
    ``n_gate[i]`` of its row (the other agents of its ``moves_with`` classes, in team
    order; M the most any agent has, at least 1)."""
    n_gate: np.ndarray
    """(R,) int64: how many of ``gate[i]`` are agent i's."""
    gate_radius_sq: np.ndarray
    """(R,) float64: how near, squared."""
    gated: np.ndarray
    """(R,) bool: agent i has a gate (its class names ``moves_with`` classes)."""
    pick_mode: np.ndarray
    """(R,) int64: 0 a command, 1 ``"pick"``, 2 ``"follow"``."""
    pick_from: np.ndarray
    """(R, C) bool: the classes agent i picks from (its ``picks``)."""
    n_picks: np.ndarray
    """(R,) int64: U, the agents of those classes (a "pick" agent's bins: U + 1)."""
    follow_radius_sq: np.ndarray
    """(R,) float64: how near a followed agent must be, squared (the sensor's radius)."""
    pick_move: np.ndarray
    """(R, 2) float64 scratch: each picking agent's move this step (:func:`pick_moves`)."""

    @classmethod
    def build(cls, config) -> Roles | None:
        """The roles of ``config`` (a :class:`~physrover.config.DomainConfig`), or None
        without ``[[agents]]``."""
        classes = config.agents
        if not classes:
            return None
        names = class_names(config)
        agent_class = agent_classes(config)
        per_class = {
            "speed": [c.max_speed for c in classes],
            "world_frame": [c.action == "world" for c in classes],
            "bounds": [c.bounds or (-math.inf, math.inf, -math.inf, math.inf) for c in classes],
            "gate_radius_sq": [gate_radius(config, c) ** 2 for c in range(len(classes))],
            "gated": [bool(c.moves_with) for c in classes],
            "pick_mode": [PICK_MODES.index(c.action) if c.action in PICK_MODES else 0
                          for c in classes],
            "pick_from": [[n in c.picks for n in names] for c in classes],
            "n_picks": [pick_count(config, c) for c in range(len(classes))],
            "follow_radius_sq": [sensor_radius(config, c) ** 2 for c in range(len(classes))],
        }  # fmt: skip
        partners = [[j for j, cj in enumerate(agent_class)
                     if j != i and names[cj] in classes[ci].moves_with]
                    for i, ci in enumerate(agent_class)]  # fmt: skip
        gate = np.zeros((len(agent_class), max(1, *map(len, partners))), np.int64)
        for i, row in enumerate(partners):
            gate[i, : len(row)] = row
        n_gate = np.array([len(row) for row in partners], np.int64)
        return cls(agent_class, **{k: np.array(v)[agent_class] for k, v in per_class.items()},
                   gate=gate, n_gate=n_gate, pick_move=np.zeros((len(agent_class), 2)))  # fmt: skip


@jit_inline
def gate_free(e, positions, roles, free):
    """Write ``free`` (R,) bool: whether each agent of team e may move this step (step 1 of
    the module docstring), from the (E, R, 2) ``positions`` before anyone moves.

    Every partner of a gated agent is looked at, without a branch on its distance: whether
    one is near is a coin toss that the branch predictor cannot learn (2026-12-06, the
    15-agent mixed team's 60 teams gated over an episode's 51 layouts: 0.36 ms with a
    branch and a class lookup per agent, 0.19 ms over its partners without)."""
    for i in range(positions.shape[1]):
        near = not roles.gated[i]
        xi, yi, reach = positions[e, i, 0], positions[e, i, 1], roles.gate_radius_sq[i]
        for m in range(roles.n_gate[i]):
            j = roles.gate[i, m]
            dx = positions[e, j, 0] - xi
            dy = positions[e, j, 1] - yi
            near |= dx * dx + dy * dy <= reach
        free[i] = near


@jit_inline
def pick_moves(e, positions, commands, roles):
    """Write ``roles.pick_move[i]``, the move of each picking agent i of team e (module
    docstring, step 3) from the (E, R, 2) ``positions`` before anyone moves and the (E, R,
    2) ``commands`` (a ``"pick"`` agent's first component, clipped here)."""
    n = positions.shape[1]
    for i in range(n):
        mode = roles.pick_mode[i]
        if mode == 0:
            continue
        xi, yi = positions[e, i, 0], positions[e, i, 1]
        target = -1
        if mode == 1:
            n_targets = roles.n_picks[i]
            a = min(max(np.float64(commands[e, i, 0]), -1.0), 1.0)
            choice = min(int((a + 1.0) * 0.5 * (n_targets + 1)), n_targets)
            for j in range(n):
                if roles.pick_from[i, roles.agent_class[j]]:
                    if choice == 0:
                        target = j
                        break
                    choice -= 1
        else:
            best = roles.follow_radius_sq[i]
            for j in range(n):
                if j != i and roles.pick_from[i, roles.agent_class[j]]:
                    dx = positions[e, j, 0] - xi
                    dy = positions[e, j, 1] - yi
                    d2 = dx * dx + dy * dy
                    if d2 <= best and (target < 0 or d2 < best):
                        best, target = d2, j
        mx = my = 0.0
        if target >= 0:
            v = roles.speed[i]
            mx = min(max(positions[e, target, 0] - xi, -v), v)
            my = min(max(positions[e, target, 1] - yi, -v), v)
        roles.pick_move[i, 0] = mx
        roles.pick_move[i, 1] = my


@jit_inline
def class_command(i, fwd, left, free, roles, cos_h, sin_h):
    """Agent i's clipped command (fwd, left) after its gate (``free``, :func:`gate_free`)
    and speed, and the frame it moves in (steps 1-3 of the module docstring): ``(fwd, left,
    cos, sin)``, the frame its heading's (``cos_h``, ``sin_h``) or the world's (1, 0: no
    turn), as the idealised move (:func:`physrover.domain.motion.ideal.ideal_move`) takes
    them."""
    if roles.pick_mode[i] != 0:  # its move is pick_moves'
        if not free[i]:
            return 0.0, 0.0, 1.0, 0.0
        return roles.pick_move[i, 0], roles.pick_move[i, 1], 1.0, 0.0
    scale = roles.speed[i] if free[i] else 0.0
    if roles.world_frame[i]:
        return fwd * scale, left * scale, 1.0, 0.0
    return fwd * scale, left * scale, cos_h, sin_h


__all__ = ["PICK_MODES", "Roles", "class_command", "gate_free", "pick_moves"]
