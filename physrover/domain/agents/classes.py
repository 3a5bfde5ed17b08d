"""Each agent's class and per-agent constants, from ``[[agents]]``.

Agents are in team order, a class's agents contiguous and in ``[[agents]]`` order: class c
owns the rows :func:`class_rows` gives of every (E, R, ...) array. Without ``[[agents]]``
the team is one class of ``n_rovers`` rovers (the paper's).
"""

from __future__ import annotations

import math

import numpy as np


def per_agent(config, per_class, default) -> np.ndarray:
    """(R,): each agent's entry of ``per_class`` (one per ``[[agents]]`` class, agents
    in team order), or ``default`` for every agent of the paper's one-class team."""
    if not config.agents:
        return np.full(config.n_rovers, default)
    return np.repeat(np.asarray(per_class), [c.count for c in config.agents])


def agent_classes(config) -> np.ndarray:
    """(R,) int64: each agent's class index (0 for every agent without ``[[agents]]``)."""
    return per_agent(config, np.arange(len(config.agents)), 0).astype(np.int64)


def counted_agents(config) -> np.ndarray:
    """(R,) bool: the agents that count toward couplings (their class ``captures``; every
    agent of the paper's team)."""
    return per_agent(config, [c.captures for c in config.agents], True).astype(bool)


def class_names(config) -> list[str]:
    """The classes' names in ``[[agents]]`` order (``["rover"]`` for the paper's team: the
    name ``[[pois]] visible_to`` and ``require`` use for it)."""
    return [c.name for c in config.agents] or ["rover"]


def class_rows(config) -> list[slice]:
    """Each class's rows of the team's (R, ...) arrays, in ``[[agents]]`` order (the
    implicit one class of the paper's rovers without them)."""
    counts = [c.count for c in config.agents] or [config.n_rovers]
    starts = np.cumsum([0, *counts])
    return [slice(int(a), int(b)) for a, b in zip(starts[:-1], starts[1:], strict=True)]


def class_sensor(config, c: int):
    """Class c's sensor: its own (``[[agents]] sensor``), else the domain's ``[sensor]``."""
    agent = config.agents[c] if config.agents else None
    return (agent.sensor if agent is not None else None) or config.sensor


def sensor_radius(config, c: int) -> float:
    """Class c's sensing radius, world units (:func:`class_sensor`'s ``radius``; inf for a
    sensor without one): what capture by sight, the gate and "follow" read."""
    return float(getattr(class_sensor(config, c), "radius", math.inf))


def pick_count(config, c: int) -> int:
    """U, the agents of class c's ``picks`` classes, which a "pick" or "follow" agent of it
    moves to (a "pick" command has U + 1 bins, its policy U + 1 outputs)."""
    picks = config.agents[c].picks
    return sum(o.count for o in config.agents if o.name in picks)


def gate_radius(config, c: int) -> float:
    """Class c's ``moves_with_radius``, or its sensor's radius for 0 (the lab's rule)."""
    return config.agents[c].moves_with_radius or sensor_radius(config, c)


def agent_names(config) -> list[str]:
    """Each agent's name: ``CLASS_j``, j counted within its class (``rover_i`` for the
    paper's team): the PettingZoo agents and TorchRL's group members."""
    if not config.agents:
        return [f"rover_{i}" for i in range(config.n_rovers)]
    return [f"{c.name}_{j}" for c in config.agents for j in range(c.count)]


def spawn_points(table, n: int, rng: np.random.Generator) -> np.ndarray | None:
    """(n, 2) start positions by the spawn rule of ``table`` (an ``[[agents]]`` or
    ``[[pois]]`` table: :func:`physrover.config.agents.check_spawn`), drawn from ``rng``
    ("box": the x then the y coordinates, uniform; "circle": the angles, uniform), or None
    where the scenario places them."""
    if table.spawn == "fixed":
        return np.asarray(table.spawn_positions, dtype=float)
    points = np.empty((n, 2))
    if table.spawn == "box":
        x0, x1, y0, y1 = table.spawn_box
        points[:, 0] = rng.uniform(x0, x1, n)
        points[:, 1] = rng.uniform(y0, y1, n)
    elif table.spawn == "circle":
        cx, cy, r = table.spawn_circle
        angle = rng.uniform(0.0, 2.0 * math.pi, n)
        points[:, 0] = cx + r * np.cos(angle)
        points[:, 1] = cy + r * np.sin(angle)
    else:
        return None
    return points


def spawn(positions: np.ndarray, config, rngs) -> None:
    """Move the start ``positions`` (E, R, 2) of the classes with a spawn rule
    (``[[agents]] spawn``), team e's from ``rngs[e]``, drawn after the scenario's (so the
    scenario's draws, and a "disc" class's start, are what they are without rules)."""
    for rows, agent in zip(class_rows(config), config.agents, strict=False):
        for e, rng in enumerate(rngs):
            points = spawn_points(agent, rows.stop - rows.start, rng)
            if points is not None:
                positions[e, rows] = points


def spawn_pois(poi_positions: np.ndarray, config, rngs) -> None:
    """Move the start ``poi_positions`` (E, K, 2) of the POIs with a spawn rule
    (``[[pois]] spawn``), POI by POI, team e's from ``rngs[e]``, drawn after the scenario's
    and the classes' (:func:`spawn`)."""
    for k, poi in enumerate(config.pois):
        for e, rng in enumerate(rngs):
            points = spawn_points(poi, 1, rng)
            if points is not None:
                poi_positions[e, k] = points[0]


__all__ = ["agent_classes", "agent_names", "class_names", "class_rows", "class_sensor",
           "counted_agents", "gate_radius", "per_agent", "pick_count", "sensor_radius",
           "spawn", "spawn_points", "spawn_pois"]  # fmt: skip
