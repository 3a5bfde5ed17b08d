"""What a domain's ``[[pois]]`` (:mod:`physrover.config.pois`) and ``[[agents]]``
(:mod:`physrover.config.agents`) tables add to :class:`~physrover.config.DomainConfig`: each
is a list of tables, and each derives a ``[domain]`` field (``poi_values`` from the POIs,
``n_rovers`` from the classes' counts), which is then not written or set on its own.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from physrover.config.agents import agents_table, check_agents, coerce_agents
from physrover.config.base import ConfigError, check
from physrover.config.pois import check_pois, coerce_pois, pois_table

ROLE_TABLES = ("pois", "agents")
"""The fields of DomainConfig that are lists of tables (``[[pois]]``, ``[[agents]]``)."""
DERIVED = {"pois": "poi_values", "agents": "n_rovers"}
"""The [domain] field each derives."""


def derive_roles(domain, sensor) -> None:
    """Coerce ``domain``'s ``pois`` and ``agents`` (``sensor``: the factory of a class's
    sensor table) and derive ``poi_values`` and ``n_rovers`` from them (in __post_init__)."""
    set_field = object.__setattr__
    set_field(domain, "pois", coerce_pois(domain.pois))
    set_field(domain, "agents", coerce_agents(domain.agents, sensor))
    if domain.pois:
        set_field(domain, "poi_values", tuple(p.value for p in domain.pois))
    if domain.agents:
        set_field(domain, "n_rovers", sum(a.count for a in domain.agents))


def check_roles(domain) -> None:
    """The checks of the POIs' and classes' tables that need the whole domain."""
    if domain.pois:
        check_pois(domain)
    if domain.agents:
        check_agents(domain)


def role_tables(domain) -> tuple[tuple[str, ...], dict[str, list[dict]]]:
    """The [domain] fields not to write (the role lists and what they derive) and the
    ``[[pois]]``/``[[agents]]`` tables to write."""
    dropped = [*ROLE_TABLES, *(DERIVED[r] for r in ROLE_TABLES if getattr(domain, r))]
    tables = {}
    if domain.pois:
        tables["pois"] = pois_table(domain.pois)
    if domain.agents:
        tables["agents"] = agents_table(domain.agents)
    return tuple(dropped), tables


def check_derived_not_given(domain_table: Mapping[str, Any], data: Mapping[str, Any]) -> None:
    """A TOML file may not give both a role's tables and the field they derive."""
    if "pois" in data and "poi_values" in domain_table:
        raise ConfigError("poi_values", "give the POIs as [[pois]] or as poi_values, not both")
    if "agents" in data and "n_rovers" in domain_table:
        try:
            total = sum(int(a.get("count", 1)) for a in data["agents"])
        except (AttributeError, TypeError, ValueError):
            return  # the tables' own checks say what is wrong with them
        if domain_table["n_rovers"] != total:
            raise ConfigError("n_rovers", f"is the sum of the [[agents]] counts ({total}); "
                              f"remove it or set it to {total}")  # fmt: skip


def check_not_overridden(domain, name: str) -> None:
    """``--set`` cannot set a role's tables, nor a field they derive (bare or
    ``domain.``-qualified)."""
    derived = [DERIVED[r] for r in ROLE_TABLES if getattr(domain, r)]
    field = name.removeprefix("domain.")
    check(field not in (*ROLE_TABLES, *derived), name,
          "set [[pois]] and [[agents]] tables in a TOML file (a sweep's: [[base.pois]], "
          "[[base.agents]]); they give poi_values and n_rovers")  # fmt: skip


def check_derived_kept(own: Mapping[str, Any], result) -> None:
    """``DomainConfig.replace`` given a derived field (``n_rovers``, ``poi_values``) whose
    value the roles of the ``result`` override: an error, not a silent change."""
    for role, field in DERIVED.items():
        if field in own and getattr(result, role):
            given = own[field]
            given = tuple(float(v) for v in given) if field == "poi_values" else given
            check(given == getattr(result, field), field,
                  f"is derived from the [[{role}]] tables ({getattr(result, field)}); change "
                  "the tables instead")  # fmt: skip


def role_fields(domain) -> dict[str, Any]:
    """The roles' fields by name, for telling runs apart (``physrover curves``):
    ``CLASS.FIELD`` (``uav.count``, ``uav.sensor.radius``) and ``pois[k].FIELD``, with the
    fields they derive; empty for the paper's domain."""
    out: dict[str, Any] = {}
    if domain.agents or domain.pois:
        out.update(n_rovers=domain.n_rovers, poi_values=domain.poi_values)
    for agent in domain.agents:
        for key, value in agent.table().items():
            if key == "sensor":
                out.update({f"{agent.name}.sensor.{k}": v for k, v in value.items()})
            else:
                out[f"{agent.name}.{key}"] = value
    for k, table in enumerate(pois_table(domain.pois)):
        out.update({f"pois[{k}].{key}": value for key, value in table.items()})
    return out


__all__ = [
    "DERIVED",
    "ROLE_TABLES",
    "check_derived_kept",
    "check_derived_not_given",
    "check_not_overridden",
    "check_roles",
    "derive_roles",
    "role_fields",
    "role_tables",
]
