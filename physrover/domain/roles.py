"""Agent classes as the compiled motion reads them (``[[agents]]``,
:mod:`physrover.config.agents`); under physical motion, :func:`class_commands` applies
steps 1-3 below to the bodies' commands instead (step 4, bounds, is idealised only).

:class:`Roles` holds each agent's class constants as arrays (agents in team order, a
class's agents contiguous), and :func:`physrover.domain.kernels.move_team` takes it as its
``roles`` argument (None, the paper's rovers, compiles it away). With roles, agent i's
move from the (forward, left) or (x, y) command ``a`` clipped to [-1, 1]:

1. *gate*: if its class names ``moves_with`` classes and no agent of them is within
   ``gate_radius`` of it at the start of the step (every agent's position before anyone
   moves: the scan its action was computed from), ``a = 0``;
2. *speed*: ``a = max_speed * a``;
3. *frame*: a body-frame agent moves as the paper's rover (``a`` in its own frame); a
   world-frame one by ``a`` itself; either way the heading turns to the move's direction;
4. *bounds*: the new position is clamped to its class's box (+-inf: none).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from physrover.domain.kernels import _gate_free
from physrover.domain.sensors import sensor_size


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

    @classmethod
    def build(cls, config) -> Roles | None:
        """The roles of ``config`` (a :class:`~physrover.config.DomainConfig`), or None
        without ``[[agents]]``."""
        classes = config.agents
        if not classes:
            return None
        names = [c.name for c in classes]
        agent_class = agent_classes(config)
        per_class = {
            "speed": [c.max_speed for c in classes],
            "world_frame": [c.action == "world" for c in classes],
            "bounds": [c.bounds or (-math.inf, math.inf, -math.inf, math.inf) for c in classes],
            "gate": [[n in c.moves_with for n in names] for c in classes],
            "gate_radius_sq": [gate_radius(c, config) ** 2 for c in classes],
        }
        return cls(agent_class,
                   **{k: np.array(v)[agent_class] for k, v in per_class.items()})  # fmt: skip


def per_agent(config, per_class, default) -> np.ndarray:
    """(R,): each agent's entry of ``per_class`` (one per ``[[agents]]`` class, agents
    in team order), or ``default`` for every agent of the paper's one-class team."""
    if not config.agents:
        return np.full(config.n_rovers, default)
    return np.repeat(np.asarray(per_class), [c.count for c in config.agents])


def agent_classes(config) -> np.ndarray:
    """(R,) int64: each agent's class index (0 for every agent without ``[[agents]]``)."""
    return per_agent(config, np.arange(len(config.agents)), 0).astype(np.int64)


def gate_radius(agent_class, config) -> float:
    """The class's ``moves_with_radius``, or its sensor's radius for 0 (the lab's rule)."""
    if agent_class.moves_with_radius:
        return agent_class.moves_with_radius
    return float(getattr(agent_class.sensor or config.sensor, "radius", math.inf))


def class_rows(config) -> list[slice]:
    """Each class's rows of the team's (R, ...) arrays, in ``[[agents]]`` order (the
    implicit one class of the paper's rovers without them)."""
    counts = [c.count for c in config.agents] or [config.n_rovers]
    starts = np.cumsum([0, *counts])
    return [slice(int(a), int(b)) for a, b in zip(starts[:-1], starts[1:], strict=True)]


def class_sensors(config) -> list[tuple]:
    """(rows, sensor, view, observation size) of each class whose agents sense differently
    from the paper's one sensor: with ``[[agents]]``, or POIs some agent may not sense
    (``[[pois]]`` ``visible_to``, ``sense_radius``, ``disappear``); else [] (the world's one
    sensor). A class-aware sensor (one with a ``view``, the lidar) gets its class's view."""
    if not (config.agents or any(p.hides for p in config.pois)):
        return []
    classes = config.agents or [None]
    out = []
    for c, (rows, agent) in enumerate(zip(class_rows(config), classes, strict=True)):
        sensor = (agent.sensor if agent is not None else None) or config.sensor
        view = sensor.view(config, c) if hasattr(sensor, "view") else None
        out.append((rows, sensor, view, sensor_size(sensor, config)))
    return out


def spawn(positions: np.ndarray, config, rngs) -> None:
    """Move the start ``positions`` (E, R, 2) of the classes with a spawn rule
    (``[[agents]] spawn``), team e's from ``rngs[e]``, drawn after the scenario's (so the
    scenario's draws, and a "disc" class's start, are what they are without rules)."""
    for rows, agent in zip(class_rows(config), config.agents, strict=False):
        n = rows.stop - rows.start
        for e, rng in enumerate(rngs):
            if agent.spawn == "fixed":
                positions[e, rows] = np.asarray(agent.spawn_positions, dtype=float)
            elif agent.spawn == "box":
                x0, x1, y0, y1 = agent.spawn_box
                positions[e, rows, 0] = rng.uniform(x0, x1, n)
                positions[e, rows, 1] = rng.uniform(y0, y1, n)
            elif agent.spawn == "circle":
                cx, cy, r = agent.spawn_circle
                angle = rng.uniform(0.0, 2.0 * math.pi, n)
                positions[e, rows, 0] = cx + r * np.cos(angle)
                positions[e, rows, 1] = cy + r * np.sin(angle)


def agent_names(config) -> list[str]:
    """Each agent's name: ``CLASS_j``, j counted within its class (``rover_i`` for the
    paper's team): the PettingZoo agents and TorchRL's group members."""
    if not config.agents:
        return [f"rover_{i}" for i in range(config.n_rovers)]
    return [f"{c.name}_{j}" for c in config.agents for j in range(c.count)]


def agent_obs_sizes(config) -> list[int]:
    """Each agent's observation size: its class's sensor's (the world pads to the widest)."""
    if not config.agents:
        return [sensor_size(config.sensor, config)] * config.n_rovers
    return [sensor_size(c.sensor or config.sensor, config) for c in config.agents
            for _ in range(c.count)]  # fmt: skip


def class_commands(actions: np.ndarray, state, roles: Roles) -> np.ndarray:
    """(E, R, 2) clipped commands as a physical body of each class takes them: the gate
    (zero unless a ``moves_with`` agent is near, judged before the step), the class's
    speed, and a world-frame (x, y) turned into the body frame of the current heading, so
    that the physical model's setpoint (the idealised move, Eq. of ``kernels._move``) is
    that (x, y). A gated body is commanded to rest; it brakes with its finite force."""
    scale = roles.speed[None, :].repeat(actions.shape[0], 0)
    for e in range(actions.shape[0]):
        scale[e] *= _gate_free(e, state.rover_positions, roles)
    out = actions * scale[..., None]
    c, s = state.cos_h, state.sin_h
    x, y = out[..., 0].copy(), out[..., 1].copy()
    world = roles.world_frame[None, :]
    out[..., 0] = np.where(world, c * x + s * y, x)
    out[..., 1] = np.where(world, c * y - s * x, y)
    return out
