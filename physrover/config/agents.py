"""Agent classes (``[[agents]]`` tables): a team as a list of classes, as the paper's lab's
later domains have it (rovers and UAVs, AADILab/influence-shaping).

Without ``[[agents]]`` a team is the paper's: ``n_rovers`` identical rovers with the
``[sensor]``. With them, each table is one class, its agents contiguous in the team in
table order (the lab: all rovers, then all UAVs), and ``n_rovers`` is the sum of the
counts. A class sets:

- ``name`` (``[a-z][a-z0-9_]*``, unique) and ``count``;
- ``captures``: whether its agents count toward a POI's coupling (the lab's rovers do, its
  UAVs do not; an agent that does not count has D = 0, except at a typed POI, ``[[pois]]
  require``, which counts exactly the classes it names);
- ``action``: ``"body"``, the paper's (forward, left) in the agent's frame, ``"world"``,
  the lab's ``dxdy`` (x, y) in the world frame, ``"pick"``, the lab's ``pick_uav`` (the
  command's first component picks one of the agents of the ``picks`` classes, or none,
  and the agent steps towards it), or ``"follow"``, the lab's fixed ``follow`` policy (the
  nearest agent of the ``picks`` classes within the agent's sensor radius; its command is
  not read): :mod:`physrover.domain.agents.roles`;
- ``picks``: the classes a ``"pick"`` or ``"follow"`` agent moves towards (the lab's UAVs);
- ``max_speed``: the command's scale per component after clipping to [-1, 1] (the lab's
  ``tanh`` output times its max velocity);
- ``sensor``: its own ``[sensor]``-style table (default: the domain's ``[sensor]``);
- ``moves_with``: class names; if given, an agent of this class moves only while an agent
  of one of them is within ``moves_with_radius`` of it (0: its sensor's radius) at the
  start of the step (the lab's ``needs_uav_to_move``, judged on the scan that chose the
  action);
- ``bounds``: ``[x_min, x_max, y_min, y_max]``, a box its agents are clamped to after each
  move (idealised motion only);
- ``influence_radius``: for the IndirectDifference credits
  (:mod:`physrover.domain.scoring.influence`), how near its agents must be to a counted
  agent to be credited with its captures;
- ``feedback``: its agents' own credit signal (the lab's per-agent ``reward_type``), in
  place of the run's ``[learn] feedback``, and ``feedback_plus_G``: G added to it (the
  lab's ``add_G``; :class:`physrover.domain.scoring.credit.ByClass`);
- ``manual_removal``: agent indices in the team whose whole trajectories the credit
  ``"ID-manual"`` leaves out of G for each agent of this class (the lab's IndirectDifference
  ``assignment = manual``);
- ``spawn``: where its agents start, the scenario's ``"disc"``, ``"fixed"`` positions, a
  ``"box"`` or a ``"circle"`` (the lab's spawn rules;
  :func:`physrover.domain.agents.classes.spawn`).

Under physical motion a class's speed, frame and gate shape its bodies' commands (its
bodies and limits are ``[physics]``'s, per agent); ``bounds`` are idealised motion's. The
CCEA trains them
(:mod:`physrover.learn.classes`); the gradient-based trainers do not.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, ClassVar

from physrover.config.base import (
    ConfigBase,
    check,
    check_choice,
    coerce_tables,
    did_you_mean,
)
from physrover.core.registry import CREDITS

ACTIONS = ("body", "world", "pick", "follow")
SPAWNS = ("disc", "fixed", "box", "circle")
NAME = re.compile(r"[a-z][a-z0-9_]*\Z")
RESERVED = ("done", "terminated", "truncated", "next", "reward", "action", "observation")
"""Names a class may not take: the TorchRL env's keys beside its groups."""


def check_spawn(table, count: int, rules: tuple[str, ...], what: str = "agent") -> None:
    """ConfigError unless the spawn fields of ``table`` (an ``[[agents]]`` or ``[[pois]]``
    table: ``spawn`` one of ``rules``, ``spawn_positions``, ``spawn_box``,
    ``spawn_circle``) fit a rule for ``count`` of ``what``
    (:func:`physrover.domain.agents.classes.spawn_points` draws them)."""
    check_choice(table.spawn, rules, "spawn")
    if table.spawn == "fixed":
        ok = len(table.spawn_positions) == count and all(
            len(p) == 2 for p in table.spawn_positions)  # fmt: skip
        check(ok, "spawn_positions", f"need one [x, y] per {what} ({count}), got "
              f"{[list(p) for p in table.spawn_positions]}")  # fmt: skip
    b = table.spawn_box
    ok = table.spawn != "box" or (len(b) == 4 and b[0] < b[1] and b[2] < b[3])
    check(ok, "spawn_box", f"need [x_min, x_max, y_min, y_max] with min < max, got {list(b)}")
    c = table.spawn_circle
    ok = table.spawn != "circle" or (len(c) == 3 and c[2] > 0)
    check(ok, "spawn_circle", f"need [cx, cy, r] with r > 0, got {list(c)}")


@dataclasses.dataclass(frozen=True)
class AgentClass(ConfigBase):
    """One ``[[agents]]`` table (module docstring)."""

    section: ClassVar[str] = "agents"

    name: str = "rover"
    """The class's name: agents are ``NAME_j`` in the envs."""
    count: int = 1
    """Agents of this class in a team."""
    captures: bool = True
    """Its agents count toward POIs' couplings."""
    action: str = "body"
    """"body": (forward, left) in the agent's frame; "world": (x, y); "pick": step towards
    the agent of ``picks`` that the command's first component picks; "follow": towards the
    nearest one in sensor range."""
    max_speed: float = 1.0
    """World units per step per action component (after clipping to [-1, 1])."""
    sensor: Any = None
    """Its [sensor] table; None: the domain's."""
    moves_with: tuple[str, ...] = ()
    """Classes one of whose agents must be near for an agent of this class to move."""
    picks: tuple[str, ...] = ()
    """Under ``action = "pick"`` or ``"follow"``: the classes whose agents it moves to."""
    moves_with_radius: float = 0.0
    """How near, world units; 0: this class's sensor radius."""
    bounds: tuple[float, ...] = ()
    """[x_min, x_max, y_min, y_max]: the box its agents are clamped to (ideal motion)."""
    influence_radius: float = 0.0
    """Its agents influence counted agents within this distance, world units, for the
    IndirectDifference credits ``ID`` and ``ID-step*`` (0: nobody; the lab's: 5)."""
    feedback: str = ""
    """Its agents' credit signal, a registered name (``physrover parts``; the lab's
    ``reward_type``: Global "G", Difference "D", IndirectDifference "ID" or "ID-step*");
    "": the run's ``[learn] feedback``."""
    feedback_plus_G: bool = False
    """Add G to its agents' credit (the lab's ``add_G``)."""
    manual_removal: tuple[int, ...] = ()
    """Agents (indices in the team) whose whole trajectories ``"ID-manual"`` removes for
    each agent of this class, the agent itself not unless listed (the lab's ``manual``)."""
    spawn: str = "disc"
    """Where its agents start: "disc" (the scenario's spawn), "fixed" (``spawn_positions``),
    "box" (uniform in ``spawn_box``) or "circle" (uniform on ``spawn_circle``)."""
    spawn_positions: tuple[tuple[float, ...], ...] = ()
    """"fixed": ``[[x, y], ...]``, one per agent."""
    spawn_box: tuple[float, ...] = ()
    """"box": ``[x_min, x_max, y_min, y_max]`` (the lab's random_uniform)."""
    spawn_circle: tuple[float, ...] = ()
    """"circle": ``[cx, cy, r]``: a point *on* the circle, its angle uniform (the lab's
    random_circle)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        check(bool(NAME.match(self.name)), "name",
              f"must match [a-z][a-z0-9_]* (it names agents), got {self.name!r}")  # fmt: skip
        check(self.name not in RESERVED, "name", f"{self.name!r} is one of the TorchRL "
              f"env's own keys; reserved: {', '.join(RESERVED)}")  # fmt: skip
        self.check_at_least(1, "count")
        check_choice(self.action, ACTIONS, "action")
        self.check_positive("max_speed")
        check(self.moves_with_radius >= 0, "moves_with_radius",
              f"must be >= 0 (0: the sensor's radius), got {self.moves_with_radius}")  # fmt: skip
        check(0 <= self.influence_radius < math.inf, "influence_radius",
              f"must be >= 0 (0: none), got {self.influence_radius}")  # fmt: skip
        check(self.feedback == "" or self.feedback in CREDITS, "feedback",
              CREDITS.unknown_message(self.feedback, ' or "" (the run\'s)'))  # fmt: skip
        b = self.bounds
        ok = not b or (len(b) == 4 and b[0] < b[1] and b[2] < b[3])
        check(ok, "bounds", f"need [x_min, x_max, y_min, y_max] with min < max, got {list(b)}")
        check_spawn(self, self.count, SPAWNS)

    def table(self) -> dict[str, Any]:
        """The TOML table (the sensor as a sub-table; no sensor: the domain's)."""
        table = self.to_dict()
        if self.sensor is None:
            del table["sensor"]
        else:
            table["sensor"] = self.sensor.table()
        return table


def coerce_agents(value, component) -> tuple[AgentClass, ...]:
    """``[[agents]]`` as AgentClasses, each sensor resolved by ``component`` (the domain's
    sensor factory); errors name ``agents[c]``."""

    def with_sensor(agent: AgentClass) -> AgentClass:
        if agent.sensor is None:
            return agent
        return dataclasses.replace(agent, sensor=component(agent.sensor))

    return coerce_tables(value, AgentClass, "agents", with_sensor)


def check_agents(domain) -> None:
    """The rules that need the whole domain: unique names, known class names, a radius for
    the gate, bounds under idealised motion, someone who can capture."""
    classes = domain.agents
    names = [c.name for c in classes]
    for c, agent in enumerate(classes):
        check(agent.name not in names[:c], f"agents[{c}].name", f"{agent.name!r} is used twice")
        for other in agent.moves_with:
            hint = did_you_mean(other, names)
            check(other in names, f"agents[{c}].moves_with",
                  f"unknown class {other!r}{hint}; classes: {', '.join(names)}")  # fmt: skip
            check(other != agent.name, f"agents[{c}].moves_with", "a class cannot gate itself")
        picking = agent.action in ("pick", "follow")
        check(picking == bool(agent.picks), f"agents[{c}].picks",
              'names the classes a "pick" or "follow" agent moves to, and only then '
              f"(action {agent.action!r})")  # fmt: skip
        for other in agent.picks:
            check(other in names, f"agents[{c}].picks", f"unknown class {other!r}"
                  f"{did_you_mean(other, names)}; classes: {', '.join(names)}")  # fmt: skip
        if agent.action == "follow":
            radius = getattr(agent.sensor or domain.sensor, "radius", math.inf)
            check(math.isfinite(radius), f"agents[{c}].sensor",
                  '"follow" moves to the nearest agent within the sensor radius: give the '
                  "sensor a finite radius")  # fmt: skip
        if agent.moves_with and not agent.moves_with_radius:
            radius = getattr(agent.sensor or domain.sensor, "radius", math.inf)
            check(math.isfinite(radius), f"agents[{c}].moves_with_radius",
                  "the sensor's radius is inf; give a finite radius")  # fmt: skip
        bad = [i for i in agent.manual_removal if not 0 <= i < domain.n_rovers]
        check(not bad, f"agents[{c}].manual_removal",
              f"agents are 0 .. {domain.n_rovers - 1} in a team, got {bad}")  # fmt: skip
        check(not agent.bounds or domain.motion == "ideal", f"agents[{c}].bounds",
              'bounds need motion = "ideal" (a physical team: [physics] walls)')  # fmt: skip
    typed = any(p.require for p in domain.pois)  # a typed POI counts the classes it names
    check(
        any(a.captures for a in classes) or typed,
        "agents",
        "no class counts toward captures (captures = true), so no POI can be captured",
    )
    counted = sum(a.count for a in classes if a.captures)
    for k, n in enumerate(domain.n_req_per_poi):
        if domain.pois and domain.pois[k].require:
            continue  # a typed coupling: its counts are checked against its classes
        where = f"pois[{k}].n_req" if domain.pois else "n_req"
        check(n <= counted, where,
              f"must be in [1, {counted}] (agents of capturing classes), got {n}")  # fmt: skip


def agents_table(classes: tuple[AgentClass, ...]) -> list[dict]:
    """The ``[[agents]]`` tables of ``classes``, as TOML writes them."""
    return [agent.table() for agent in classes]


__all__ = ["ACTIONS", "SPAWNS", "AgentClass", "agents_table", "check_agents", "check_spawn",
           "coerce_agents"]  # fmt: skip
