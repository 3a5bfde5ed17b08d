"""POIs with rules (``[[pois]]`` tables): per-POI value, coupling, capture radius, order and
scoring time, beyond the paper's POIs that differ only in value.

Without ``[[pois]]`` a domain's POIs are the paper's: ``[domain] poi_values`` and ``n_req``
(one number or one per POI), captured within ``d_cap`` at any scored step (Eqs. 11-13).
With them, each table is one POI, in order, and may set:

- ``value`` V_k (default 1.0);
- ``n_req``, its coupling (default 0: ``[domain] n_req``, so a sweep's grid over ``n_req``
  still sets every POI's);
- ``capture_radius`` (default 0: ``[domain] d_cap``), world units, at least ``d_min``;
- ``capture_by``: which agents are in its range (Eq. 13): ``"radius"`` (within
  ``capture_radius``: the paper's), ``"sight"`` (within both the agent's sensing radius and
  the POI's ``sense_radius``) or ``"radius-or-sight"`` (either: the lab's rule,
  AADILab/influence-shaping ``custom_env.AbstractRoverConstraint.captured``; its POIs
  without a ``capture_radius`` are ``"sight"``);
- ``value_by``: ``"capture"`` (V_k once captured, Eq. 11: the paper's) or ``"distance"``
  (the lab's distance-scored value, AADILab/influence-shaping ``custom_env.py``
  ``AbstractRoverConstraint._step_is_satisfied``: at a scored step where its coupling is
  met, ``n_req x prod_j 1 / max(1, d_j)`` over the ``n_req`` smallest distances d_j of the
  agents that count for it, in range or not, multiplied nearest first; else 0. G adds V_k
  times its best such value over the scored steps, ``score_at = "any"``, the lab's
  ``sequential``, or its value at the last scored step, ``"final"``, the lab's ``final``);
- ``after``, the indices of earlier POIs that must have been captured at an *earlier* step
  before this one counts (an ordered chain takes a step per link). Scoring applies it to
  the team and to every counterfactual of D alike: without rover i, POI k counts only after
  its predecessors were captured without rover i;
- ``score_at``: ``"any"`` (Eq. 11's max over the scored steps: the paper's, and the lab's
  ``sequential`` constraint) or ``"final"`` (only the last scored state counts: the lab's
  ``final`` constraint);
- ``require``: a typed coupling, ``{rover = 2, uav = 1}``: at least that many agents of
  each named class at one step, instead of ``n_req`` (only their agents count for it);
- what senses it (scoring is unchanged; the lidar applies these, the density sensor
  cannot): ``visible_to``, the agent classes that sense it (the lab's hidden POIs are
  visible to its UAVs only), ``sense_radius``, the distance within which it is sensed, and
  ``disappear``: ``"captured"``, no longer sensed once captured (from the step after), or
  ``"visited"``, no longer sensed once an agent of the classes ``visited_by`` (default:
  every class that captures) comes within ``visit_radius`` (default 1.0) of it and within
  its own sensor's radius (from that state on: the lab's ``disappear_bool``, which a
  rover's SmartLidar scan sets before the UAVs scan; :mod:`physrover.domain.sensing.vanish`).

The scenario still places the POIs; ``poi_values`` is derived from the tables (values may
repeat there). The compiled scoring is :func:`physrover.domain.scoring.captures.score_team`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, ClassVar

from physrover.config.agents import check_spawn
from physrover.config.base import ConfigBase, check, check_choice, coerce_tables, did_you_mean

SCORE_AT = ("any", "final")
CAPTURE_BY = ("radius", "sight", "radius-or-sight")
VALUE_BY = ("capture", "distance")
DISAPPEAR = ("never", "captured", "visited")
SPAWNS = ("scenario", "fixed", "box", "circle")
"""Where a POI starts: the scenario's place for it, or a rule of its own (as an agent's)."""


@dataclasses.dataclass(frozen=True)
class PoiRule(ConfigBase):
    """One ``[[pois]]`` table (module docstring)."""

    section: ClassVar[str] = "pois"

    value: float = 1.0
    """V_k, the POI's value in G (Eq. 11)."""
    n_req: int = 0
    """Agents needed within the capture radius at one step (Eq. 12); 0: [domain] n_req."""
    capture_radius: float = 0.0
    """World units (Eq. 13); 0: [domain] d_cap."""
    capture_by: str = "radius"
    """Which agents are in its range (module docstring): "radius", "sight" (within the
    agent's sensing radius and ``sense_radius``) or "radius-or-sight" (the lab's)."""
    value_by: str = "capture"
    """What it adds to G: V_k once "capture"d (Eq. 11), or V_k times the lab's "distance"
    value of its agents (module docstring)."""
    after: tuple[int, ...] = ()
    """Indices of earlier POIs captured at an earlier step before this one counts."""
    score_at: str = "any"
    """"any" scored step (Eq. 11) or only the "final" one."""
    visible_to: tuple[str, ...] = ()
    """The agent classes that sense it (empty: every class); the lab's hidden POIs are
    ``["uav"]``."""
    sense_radius: float = math.inf
    """It is sensed only within this distance, world units (and the sensor's radius)."""
    disappear: str = "never"
    """"never", "captured" (no longer sensed once captured) or "visited" (once an agent of
    ``visited_by`` came within ``visit_radius``); scoring is unchanged."""
    visit_radius: float = 1.0
    """"visited": within this distance, world units (the lab's hard-coded 1.0)."""
    visited_by: tuple[str, ...] = ()
    """"visited": the classes whose agents mark it (empty: every class that captures)."""
    require: Any = dataclasses.field(default_factory=dict)
    """``{class = count}``: a typed coupling, at least ``count`` agents of each named class
    at one step (instead of ``n_req``); only those classes' agents count for it."""
    spawn: str = "scenario"
    """Where it starts each episode: "scenario" (where the scenario puts it), "fixed"
    (``spawn_positions``), "box" (uniform in ``spawn_box``) or "circle" (on
    ``spawn_circle``): the lab's per-POI ``position.spawn_rule``, drawn after the
    scenario and the agents' spawns."""
    spawn_positions: tuple[tuple[float, ...], ...] = ()
    """"fixed": ``[[x, y]]``."""
    spawn_box: tuple[float, ...] = ()
    """"box": ``[x_min, x_max, y_min, y_max]`` (the lab's random_uniform)."""
    spawn_circle: tuple[float, ...] = ()
    """"circle": ``[cx, cy, r]``: a point *on* the circle, its angle uniform (the lab's
    random_circle)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        check(self.value > 0 and self.value != float("inf"), "value",
              f"must be positive and finite, got {self.value}")  # fmt: skip
        check(self.n_req >= 0, "n_req", f"must be >= 1 (0: [domain] n_req), got {self.n_req}")
        radius = self.capture_radius
        check(0 <= radius < float("inf"), "capture_radius",
              f"must be >= d_min (0: d_cap), got {radius}")  # fmt: skip
        check_choice(self.score_at, SCORE_AT, "score_at")
        check_choice(self.capture_by, CAPTURE_BY, "capture_by")
        check_choice(self.value_by, VALUE_BY, "value_by")
        for field, given in (("after", self.after), ("require", self.require)):
            check(self.value_by == "capture" or not given, field,
                  'is not defined for value_by = "distance" (the lab has no such POI)')  # fmt: skip
        check(self.capture_by != "sight" or radius == 0, "capture_radius",
              'is not used under capture_by = "sight" (leave it 0)')  # fmt: skip
        check(self.sense_radius > 0, "sense_radius", f"must be > 0, got {self.sense_radius}")
        check_choice(self.disappear, DISAPPEAR, "disappear")
        check(0 < self.visit_radius < math.inf, "visit_radius",
              f"must be > 0 and finite, got {self.visit_radius}")  # fmt: skip
        for field in ("visit_radius", "visited_by"):
            check(self.disappear == "visited" or self.is_default(field), field,
                  'is read only under disappear = "visited"')  # fmt: skip
        require = self.require
        check(isinstance(require, Mapping), "require",
              f"expected a table {{class = count}}, got {require!r}")  # fmt: skip
        for name, n in require.items():
            check(isinstance(n, int) and not isinstance(n, bool) and n >= 1,
                  f"require.{name}", f"must be an integer >= 1, got {n!r}")  # fmt: skip
        object.__setattr__(self, "require", dict(require))
        check(not (require and self.n_req), "require", "give n_req or require, not both")
        check_spawn(self, 1, SPAWNS, "POI")

    @property
    def scored_by_rule(self) -> bool:
        """Whether it scores by a rule (``after``, ``score_at = "final"``, ``require``,
        ``value_by = "distance"``), not by a count of agents in range at any scored step as
        the paper's POIs do."""
        return (bool(self.after) or self.score_at != "any" or bool(self.require)
                or self.value_by != "capture")  # fmt: skip

    @property
    def hides(self) -> bool:
        """Whether some agent may not sense it (``visible_to``, ``sense_radius``,
        ``disappear``): only a class-aware sensor (the lidar) can apply that."""
        return bool(self.visible_to) or math.isfinite(self.sense_radius) or (
            self.disappear != "never")  # fmt: skip


def coerce_pois(value) -> tuple[PoiRule, ...]:
    """``[[pois]]`` as PoiRules: a list of tables or of PoiRule; errors name ``pois[k]``."""
    return coerce_tables(value, PoiRule, "pois")


def check_pois(domain) -> None:
    """The rules that need the rest of the domain: couplings within the team, radii at least
    d_min, ``after`` naming earlier POIs that can be captured before the end."""
    pois = domain.pois
    check(not isinstance(domain.n_req, tuple), "n_req",
          "give each POI's coupling in its [[pois]] table, not as a list")  # fmt: skip
    for k, rule in enumerate(pois):
        n_req = rule.n_req or domain.n_req
        check(bool(rule.require) or 1 <= n_req <= domain.n_rovers, f"pois[{k}].n_req",
              f"must be in [1, n_rovers={domain.n_rovers}], got {n_req}")  # fmt: skip
        radius = rule.capture_radius
        check(radius == 0 or radius >= domain.d_min, f"pois[{k}].capture_radius",
              f"must be >= d_min ({domain.d_min}) or 0 (d_cap), got {radius}")  # fmt: skip
        for j in rule.after:
            check(0 <= j < k, f"pois[{k}].after",
                  f"must list earlier POIs (indices < {k}), got {list(rule.after)}")  # fmt: skip
            final = f"POI {j} is scored at the final state only, so POI {k} could never count"
            check(pois[j].score_at == "any", f"pois[{k}].after", final)
        names = [c.name for c in domain.agents] or ["rover"]
        sizes = {c.name: c.count for c in domain.agents} or {"rover": domain.n_rovers}
        for name, n in rule.require.items():
            check(name in names, f"pois[{k}].require",
                  f"unknown class {name!r}{did_you_mean(name, names)}; classes: "
                  f"{', '.join(names)}")  # fmt: skip
            check(n <= sizes[name], f"pois[{k}].require.{name}",
                  f"must be in [1, {sizes[name]}] (the class's count), got {n}")  # fmt: skip
        for field in ("visible_to", "visited_by"):
            for name in getattr(rule, field):
                check(name in names, f"pois[{k}].{field}",
                      f"unknown class {name!r}{did_you_mean(name, names)}; classes: "
                      f"{', '.join(names)}")  # fmt: skip
    if any(rule.hides for rule in pois):
        sensors = [(f"agents[{c}].sensor", a.sensor or domain.sensor)
                   for c, a in enumerate(domain.agents)] or [("sensor", domain.sensor)]  # fmt: skip
        for where, sensor in sensors:
            aware = not getattr(sensor, "senses_pois", True) or (  # none to hide from it
                hasattr(sensor, "view") and hasattr(sensor, "observe_class")
            )
            check(aware, where,
                  f"{sensor.kind!r} cannot hide POIs (visible_to, sense_radius, disappear); "
                  'use kind = "lidar"')  # fmt: skip


def pois_table(pois: tuple[PoiRule, ...]) -> list[dict]:
    """The ``[[pois]]`` tables of ``pois``, as TOML writes them."""
    tables = [rule.to_dict() for rule in pois]
    for table in tables:  # TOML has no empty inline table to write
        if not table["require"]:
            del table["require"]
        if table["spawn"] == "scenario":  # written only where given, as before they existed
            for name in ("spawn", "spawn_positions", "spawn_box", "spawn_circle"):
                del table[name]
        if table["disappear"] != "visited":
            del table["visit_radius"], table["visited_by"]
    return tables


def capture_radii(domain) -> list[float]:
    """Each POI's capture radius, world units: its own ``capture_radius``, or ``d_cap``
    where it has none (0, or no ``[[pois]]``)."""
    own = [p.capture_radius for p in domain.pois] or [0.0] * domain.n_pois
    return [radius or domain.d_cap for radius in own]


__all__ = [
    "CAPTURE_BY",
    "DISAPPEAR",
    "SCORE_AT",
    "SPAWNS",
    "VALUE_BY",
    "PoiRule",
    "capture_radii",
    "check_pois",
    "coerce_pois",
    "pois_table",
]
