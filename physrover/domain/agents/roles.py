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
   (:func:`class_command`, then :func:`physrover.domain.motion.ideal.ideal_move`);
4. *bounds*: the new position is clamped to its class's box (+-inf: none; idealised motion
   only, the config refuses bounds under physics).

Under physical motion steps 1-3 make the body's setpoint (the idealised move, which the
controller then tracks with finite force).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from physrover.core.compiled import jit, jit_inline
from physrover.domain.agents.classes import agent_classes, class_names, gate_radius


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
    """(R, C) bool: the classes that must be near for agent i to move (none: always)."""
    gate_radius_sq: np.ndarray
    """(R,) float64: how near, squared."""
    gated: np.ndarray
    """(R,) bool: agent i has a gate (``gate[i].any()``)."""

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
            "gate": [[n in c.moves_with for n in names] for c in classes],
            "gate_radius_sq": [gate_radius(c, config) ** 2 for c in classes],
            "gated": [bool(c.moves_with) for c in classes],
        }
        return cls(agent_class,
                   **{k: np.array(v)[agent_class] for k, v in per_class.items()})  # fmt: skip


@jit
def gate_free(e, positions, roles, free):
    """Write ``free`` (R,) bool: whether each agent of team e may move this step (step 1 of
    the module docstring), from the (E, R, 2) ``positions`` before anyone moves."""
    n = positions.shape[1]
    for i in range(n):
        free[i] = True
        if not roles.gated[i]:
            continue
        free[i] = False
        xi, yi = positions[e, i, 0], positions[e, i, 1]
        for j in range(n):
            if j != i and roles.gate[i, roles.agent_class[j]]:
                dx = positions[e, j, 0] - xi
                dy = positions[e, j, 1] - yi
                if dx * dx + dy * dy <= roles.gate_radius_sq[i]:
                    free[i] = True
                    break


@jit_inline
def class_command(i, fwd, left, free, roles, cos_h, sin_h):
    """Agent i's clipped command (fwd, left) after its gate (``free``, :func:`gate_free`)
    and speed, and the frame it moves in (steps 1-3 of the module docstring): ``(fwd, left,
    cos, sin)``, the frame its heading's (``cos_h``, ``sin_h``) or the world's (1, 0: no
    turn), as the idealised move (:func:`physrover.domain.motion.ideal.ideal_move`) takes
    them."""
    scale = roles.speed[i] if free[i] else 0.0
    if roles.world_frame[i]:
        return fwd * scale, left * scale, 1.0, 0.0
    return fwd * scale, left * scale, cos_h, sin_h


__all__ = ["Roles", "class_command", "gate_free"]
