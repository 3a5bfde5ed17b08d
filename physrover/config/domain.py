"""The domain's configuration: ``[domain]``, ``[physics]``, ``[failures]``, ``[scenario]`` and
``[sensor]``.

Field names are the public vocabulary of physrover: the same names are used in TOML files,
on the command line (``--set n_req=5``, ``--set physics.substeps=2``) and as keyword
arguments of the gymnasium environments (``RoverVectorEnv(50, n_req=5, collisions=False)``).
A bare name is looked up in [domain], then [physics], [failures], the scenario's and the
sensor's tables (a name in two of them must be written ``table.field``).

The scenario (start states) and the sensor (observations) are components chosen by name
(``[scenario] kind = "ring"``, :mod:`physrover.domain.scenarios`; ``[sensor] kind =
"density"``, :mod:`physrover.domain.sensing.sensor`); the motion model by ``[domain] motion``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, ClassVar

from physrover.config.base import (
    Component,
    ConfigBase,
    ConfigError,
    check,
    check_choice,
    coerce,
    coerce_table,
    component,
    did_you_mean,
    dumps_toml,
    loads_toml,
)
from physrover.config.failures import FailureConfig
from physrover.config.physics import PhysicsConfig
from physrover.config.roles import (
    ROLE_TABLES,
    check_derived_kept,
    check_derived_not_given,
    check_roles,
    derive_roles,
    role_tables,
)
from physrover.core.registry import DYNAMICS, SCENARIOS, SENSORS

COMPONENTS = ("physics", "failures", "scenario", "sensor")
"""The fields of :class:`DomainConfig` that hold a table of their own."""
TABLES = {"physics": PhysicsConfig, "failures": FailureConfig}
"""The components that are one fixed table (the others are registered kinds), by field."""
REGISTRIES = {"scenario": SCENARIOS, "sensor": SENSORS}
DEFAULT_KINDS = {"scenario": "ring", "sensor": "density"}
"""The kinds a scenario and a sensor have when a config names none (the paper's)."""
SCORED_STATES = ("all", "before-steps")


def extent_of(scenario, n_rovers: int, spawn: bool = False) -> float:
    """The scenario's :meth:`~Scenario.extent` (``spawn``: :meth:`~Scenario.spawn_extent`)
    for a team of ``n_rovers``: through ``extent_for`` / ``spawn_extent_for`` where the
    scenario defines them (its start depends on the team's size), else the plain ones."""
    sized = getattr(scenario, "spawn_extent_for" if spawn else "extent_for", None)
    if sized is not None:
        return float(sized(n_rovers))
    return float(scenario.spawn_extent() if spawn else scenario.extent())


@dataclasses.dataclass(frozen=True)
class DomainConfig(ConfigBase):
    """The tightly coupled multi-rover domain (paper Sections 4.1-4.2).

    Distances are in world units (the paper's: capture radius 4, POI ring radius 15); one
    environment step is one time step ``t`` of Eqs. 11-16. Defaults are the paper's values.
    ``physics``, ``failures``, ``scenario`` and ``sensor`` hold their own tables; each
    accepts an instance, a table (mapping), or for the scenario and sensor a registered
    kind's name.
    """

    section: ClassVar[str] = "domain"

    n_rovers: int = 15
    """Rovers per team (the paper varies 6-15)."""
    poi_values: tuple[float, ...] = (1.0, 2.0, 3.0, 4.0)
    """Value V_k of each POI; distinct and positive (the paper: 1..4, max score 10). Their
    number is the number of POIs; the scenario places them."""
    n_req: Any = 3
    """Coupling: rovers needed within d_cap of a POI at one step to capture it (Eq. 12);
    one number for every POI, or a list of one per POI (see :attr:`n_req_per_poi`)."""
    d_cap: float = 4.0
    """Capture radius, world units (Eq. 13)."""
    d_min: float = 1.0
    """Lower bound of the distance metric, world units (Eq. 14)."""
    steps: int = 50
    """Time steps per episode."""
    scored_states: str = "all"
    """Which states count for captures (Eqs. 11-12): "all", s_0 .. s_T (the start and the
    state after every step, physrover's default), or "before-steps", s_0 .. s_{T-1} (the
    lab's rover-domain code: the state before each step; the final state never counts)."""
    motion: str = "ideal"
    """Motion model: "ideal" (the paper's kinematics) or "physics" (rigid bodies with
    finite force, its parameters in [physics]); any registered in
    :data:`physrover.core.registry.DYNAMICS`."""
    physics: Any = None
    """[physics]: a :class:`PhysicsConfig` (used when motion = "physics")."""
    failures: Any = None
    """[failures]: a :class:`~physrover.config.failures.FailureConfig`, agents that fail
    mid-episode (default: none)."""
    scenario: Any = None
    """[scenario]: start states (default ``"ring"``, the paper's)."""
    sensor: Any = None
    """[sensor]: what a rover observes (default ``"density"``, Eqs. 15-16 in quadrants)."""
    pois: Any = ()
    """``[[pois]]``: POIs with rules (:mod:`physrover.config.pois`), one table per POI; when
    given, ``poi_values`` is derived from them. Empty: the paper's POIs."""
    agents: Any = ()
    """``[[agents]]``: agent classes (:mod:`physrover.config.agents`), one table per class;
    when given, ``n_rovers`` is the sum of their counts. Empty: the paper's rovers."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        for name, table in TABLES.items():
            object.__setattr__(self, name, coerce_table(getattr(self, name), table))
        physics = self.physics
        for section in ("scenario", "sensor"):
            value = component(getattr(self, section), REGISTRIES[section], section,
                              DEFAULT_KINDS[section])  # fmt: skip
            object.__setattr__(self, section, value)
        derive_roles(self, lambda table: component(table, SENSORS, "sensor", "density"))
        check(self.n_rovers >= 1, "n_rovers", f"must be >= 1, got {self.n_rovers}")
        check(len(self.poi_values) >= 1, "poi_values", "must list at least one POI value")
        for v in self.poi_values:
            check(
                v > 0 and math.isfinite(v),
                "poi_values",
                f"every value must be positive and finite, got {v}",
            )
        check(
            len(set(self.poi_values)) == len(self.poi_values) or self.pois,
            "poi_values",
            f"values must be distinct, got {list(self.poi_values)}",
        )
        object.__setattr__(self, "n_req", self._coerced_n_req())
        check_roles(self)
        for n in self.n_req_per_poi:
            check(
                1 <= n <= self.n_rovers,
                "n_req",
                f"must be in [1, n_rovers={self.n_rovers}], got {n}",
            )
        check_choice(self.scored_states, SCORED_STATES, "scored_states")
        self.check_positive("d_cap", "d_min")
        check(
            self.d_min <= self.d_cap,
            "d_min",
            f"must be in (0, d_cap={self.d_cap}], got {self.d_min}",
        )
        check(self.steps >= 1, "steps", f"must be >= 1, got {self.steps}")
        check(self.motion in DYNAMICS, "motion", DYNAMICS.unknown_message(self.motion))
        self.scenario.check_domain(self)
        check(
            getattr(DYNAMICS[self.motion], "obstacles", False)
            or len(self.scenario.obstacle_capsules()) == 0,
            "motion",
            f"{self.motion!r} motion cannot hold the scenario's obstacles (the paper's "
            'kinematics has none); use motion = "physics" or a scenario without obstacles',
        )
        physics.check_rovers(self.n_rovers)
        self.failures.check_domain(self.n_rovers, self.steps)
        steered = [a.name for a in self.agents if a.action in ("pick", "follow")]
        check(not (self.failures.on and steered and self.motion != "ideal"), "failures",
              f"agents that pick or follow ({', '.join(steered)}) would keep moving after "
              f"they fail under {self.motion!r} motion; failures take them under the "
              "idealised motion only")  # fmt: skip
        if physics.walls:
            radius = float(physics.per_rover("rover_radius", self.n_rovers).max())
            inner = extent_of(self.scenario, self.n_rovers, spawn=True) + 2 * radius
            check(
                physics.wall_half_size > inner,
                "wall_half_size",
                f"must exceed the scenario's spawn extent + 2 rover_radius = {inner}, got "
                f"{physics.wall_half_size}",
            )

    def _coerced_n_req(self) -> int | tuple[int, ...]:
        if isinstance(self.n_req, (list, tuple)):
            n_req = tuple(coerce("n_req", int, n) for n in self.n_req)
            check(
                len(n_req) == len(self.poi_values),
                "n_req",
                f"a list needs one coupling per POI ({len(self.poi_values)}), got {len(n_req)}",
            )
            return n_req
        return coerce("n_req", int, self.n_req)

    @property
    def n_pois(self) -> int:
        return len(self.poi_values)

    @property
    def n_req_per_poi(self) -> tuple[int, ...]:
        """The coupling of each POI, in the order of ``poi_values``."""
        n_req = self.n_req
        if self.pois:  # a typed POI's: the agents it requires in all
            return tuple(sum(p.require.values()) or p.n_req or n_req for p in self.pois)
        return n_req if isinstance(n_req, tuple) else (n_req,) * len(self.poi_values)

    # -- flat names ------------------------------------------------------------------------

    def tables(self) -> dict[str, dict[str, Any]]:
        """{section: table} of [domain], [physics], [failures] (if any agent can fail: a
        config without it reads as it did before the table existed), [scenario], [sensor]
        (and ``pois`` and ``agents``, lists of tables, if any), as in TOML."""
        dropped, lists = role_tables(self)
        own = {k: v for k, v in self.to_dict().items() if k not in (*COMPONENTS, *dropped)}
        return {
            "domain": own,
            "physics": self.physics.to_dict(),
            **({"failures": self.failures.to_dict()} if self.failures.on else {}),
            "scenario": self.scenario.table(),
            "sensor": self.sensor.table(),
            **lists,
        }

    def flat_dict(self) -> dict[str, Any]:
        """Every field by its bare name (the scenario's and sensor's kinds as ``scenario``
        and ``sensor``): what ``--set`` and the envs' keyword arguments address."""
        t = self.tables()
        flat = {**t["domain"], **t["physics"], **self.failures.to_dict()}
        for section in ("scenario", "sensor"):
            table = dict(t[section])
            flat[section] = table.pop("kind")
            flat.update(table)
        return flat

    def replace(self, **changes: Any) -> DomainConfig:
        """A copy with ``changes`` applied and validated once, as a whole.

        Names are bare (``substeps``) or dotted (``physics.substeps``, ``domain.n_req``,
        ``scenario.kind``); ``scenario="NAME"`` or ``sensor="NAME"`` picks that kind with its
        defaults (the current parameters if it is the current kind), and its fields may
        follow in the same call. A bare name that two of the tables have is an error that
        says which to write.
        """
        changes = dict(changes)
        for section in COMPONENTS:
            if f"{section}.kind" in changes:  # the TOML spelling of a kind change
                changes[section] = changes.pop(f"{section}.kind")
            if f"domain.{section}" in changes:
                changes[section] = changes.pop(f"domain.{section}")
        parts = {
            **{
                name: coerce_table(changes.pop(name, getattr(self, name)), table)
                for name, table in TABLES.items()
            },
            "scenario": self._component("scenario", changes.pop("scenario", self.scenario)),
            "sensor": self._component("sensor", changes.pop("sensor", self.sensor)),
        }
        own, fields = {}, {name: {} for name in COMPONENTS}
        for name, value in changes.items():
            section, _, field = name.rpartition(".")
            if section in COMPONENTS:
                fields[section][field] = value
            elif section == "domain" or (not section and name in self.field_names()):
                own[field] = value
            else:
                holders = [p for p in COMPONENTS if field in parts[p].field_names()]
                if section or not holders:
                    known = [*self.field_names(), *(f for p in parts.values()
                                                    for f in p.field_names())]  # fmt: skip
                    hint = did_you_mean(field, known)
                    raise ConfigError(name, f"unknown DomainConfig field{hint}")
                if len(holders) > 1:
                    raise ConfigError(name, f"is in [{holders[0]}] and [{holders[1]}]: write "
                                      f"{holders[0]}.{name} or {holders[1]}.{name}")  # fmt: skip
                fields[holders[0]][field] = value
        for section, values in fields.items():
            if values:
                parts[section] = parts[section].replace(**values)
        result = DomainConfig(**{**self.to_dict(), **own, **parts})
        check_derived_kept(own, result)
        return result

    def _component(self, section: str, value: Any):
        """The scenario or sensor ``value`` names; the current one for its own kind's name."""
        current = getattr(self, section)
        if isinstance(value, str) and value == current.kind:
            return current
        return component(value, REGISTRIES[section], section, DEFAULT_KINDS[section])

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> DomainConfig:
        """From the [domain] table, optionally with bare names of the other tables' fields
        (the envs' keyword arguments; the layout of run directories before 0.2)."""
        return cls().replace(**values) if values else cls()

    def to_toml(self) -> str:
        return dumps_toml(self.tables())

    @classmethod
    def from_toml(cls, text: str) -> DomainConfig:
        data = loads_toml(text)
        unknown = sorted(set(data) - {"domain", *COMPONENTS, *ROLE_TABLES})
        if unknown:
            raise ConfigError(unknown[0], "unknown TOML table (expected [domain], [physics], "
                              "[failures], [scenario], [sensor], [[pois]] or "
                              "[[agents]])")  # fmt: skip
        return cls.from_tables(data)

    @classmethod
    def from_tables(cls, data: Mapping[str, Any]) -> DomainConfig:
        """From the [domain], [physics], [failures], [scenario], [sensor], [[pois]] and
        [[agents]] tables of a TOML file."""
        domain = dict(data.get("domain", {}))
        check_derived_not_given(domain, data)
        for section in (*COMPONENTS, *ROLE_TABLES):
            if section in domain and section in data:
                raise ConfigError(f"domain.{section}", f"given in [domain] and as [{section}]")
            if section in data:
                domain[section] = data[section]
        return cls.from_dict(domain)


__all__ = ["COMPONENTS", "Component", "DomainConfig", "FailureConfig", "PhysicsConfig"]
