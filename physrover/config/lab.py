"""The paper's lab's experiment configs, read into physrover's (AADILab/influence-shaping).

The lab describes a run in one YAML file (``env``: agents, POIs, map; ``ccea``: the
algorithm); :func:`lab_domain` turns its ``env`` section into a
:class:`~physrover.config.DomainConfig`, refusing with one line (a
:class:`~physrover.config.ConfigError` naming the lab's key) what physrover cannot express.
The conventions, each the lab's code as it runs (``src/influence/custom_env.py``
``createEnv``, ``createAgent``; the C++ ``RewardComputer``):

- *Agents*: the lab's rovers, then its UAVs, in order (its agent indices are physrover's).
  Consecutive agents of one type whose tables differ at most in their fixed spawn position
  are one ``[[agents]]`` class (``rover``, ``uav``; ``rover_1``, ``rover_2``, ... where a
  type needs several). Rovers count toward captures, UAVs do not and influence rovers
  within 5 (the lab's hard-coded influence radius). ``dxdy`` is ``action = "world"``
  with the class's max speed (``ccea.network.{rover,uav}_max_velocity``), ``pick_uav``
  ``action = "pick"`` (with the ``follow`` policy: ``"follow"``) picking the UAV classes
  (``UavDistanceLidar`` is ``kind = "distances"`` to them), bounded to the
  map (``bounds``, default ``[0, map_size]``); ``needs_uav_to_move`` is ``moves_with =
  ["uav"]`` within the rover's observation radius.
- *Sensors*: an agent's observation radius is its class's lidar radius (what capture by
  sight reads); ``SmartLidar`` (and ``RoverLidar``, which senses no POI: every POI is
  hidden from its class, so its POI block reads ``empty``, inputs the lab's network does
  not have) is the lidar with ``channels = "by-class"``, sectors of
  ``resolution`` degrees fixed in the world frame, ``accum_type`` sum or average
  (``compose`` "density" or "average"), ``measurement_type`` ``inverse_distance_squared``
  or ``one_minus_inverse_distance_over_observation_radius`` (``measure``
  "inverse-square" or "linear") and ``default_value`` (``empty``, default -1).
- *Credit*: each agent's ``reward_type`` is its class's ``feedback``: Global "G",
  Difference "D", IndirectDifference "ID" (``timescale: trajectory``), "ID-step",
  "ID-step-local", "ID-step-system" or "ID-step-difference" (``timestep`` with
  ``credit`` AllOrNothing, Local, System or Difference), or "ID-manual" (``assignment:
  manual``, its list ``manual_removal``); ``add_G`` is ``feedback_plus_G``.
- *POIs*: ``rover_pois`` then ``hidden_pois`` (seen by UAVs only: ``visible_to``), each
  valued by distance (``value_by = "distance"``, the lab's only POI), ``coupling`` its
  ``n_req``, ``constraint`` final (the default) or sequential (``score_at`` "final" or
  "any"), captured within ``capture_radius`` or by sight (``capture_by``), gone from
  sight once a rover that senses by SmartLidar comes within 1.0 under ``disappear_bool``
  (``disappear = "visited"``, ``visited_by`` those rovers' classes, on a hidden POI:
  elsewhere the lab's flag does nothing); a
  hidden POI's ``subtype`` sensed only by the UAVs that list it in their
  ``observable_subtypes`` (its ``visible_to``; a rover POI's subtype is never read, as in
  the lab's SmartLidar); fixed
  positions are an ``explicit`` scenario, positions on one ``random_circle`` a ``ring-random`` one
  around the circle's centre, which is then physrover's origin (every agent position, box
  and bound moves with it: distances, bearings and moves do not change); POIs that spawn
  by rules of their own (random boxes or circles of their own, or mixed with fixed ones)
  each take theirs as ``[[pois]] spawn``, drawn once per generation.

The differences physrover keeps on purpose (its credits' pages list them: AllOrNothing's
agent 0) are physrover's rules here too; ``feedback = "ID-step-all-or-nothing-lab"`` is the
lab's AllOrNothing as its code computes it, for a lab user who needs its numbers back.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from physrover.config.base import ConfigError
from physrover.config.domain import DomainConfig

INFLUENCE_RADIUS = 5.0
"""The lab's influence radius (``computer.hpp``, ``is_influencing``), world units."""

LAB_D_MIN = math.sqrt(0.001)
"""The lab's lidar floors d^2 at 0.001 (``lidar.hpp``): physrover's ``d_min`` (Eq. 14)."""

LAB_REWARDS = {"Global": "G", "Difference": "D"}
LAB_STEP_CREDITS = {"AllOrNothing": "ID-step", "Local": "ID-step-local",
                    "System": "ID-step-system", "Difference": "ID-step-difference"}  # fmt: skip
LAB_ACCUM = {"sum": "density", "average": "average"}
LAB_MEASURES = {"inverse_distance_squared": "inverse-square",
                "one_minus_inverse_distance_over_observation_radius": "linear",
                "inverse_distance": "inverse", "exponential_negative_distance": "exponential",
                "distance_over_observation_radius": "ratio"}  # fmt: skip
LAB_CONSTRAINTS = {"final": "final", "sequential": "any"}


def get(table: dict, key: str, where: str, default: Any = ...) -> Any:
    """``table[key]``, or ``default``; a ConfigError naming the lab's key if missing."""
    if key in table:
        return table[key]
    if default is ...:
        raise ConfigError(f"{where}.{key}", "missing (the lab's code needs it)")
    return default


def _feedback(agent: dict, where: str) -> dict[str, Any]:
    """The ``[[agents]]`` credit fields of one lab agent (module docstring)."""
    reward = get(agent, "reward_type", where)
    params = agent.get("IndirectDifference") or {}
    fields: dict[str, Any] = {"feedback_plus_G": bool(params.get("add_G", False))}
    if reward in LAB_REWARDS:
        fields["feedback"] = LAB_REWARDS[reward]
        return fields
    if reward != "IndirectDifference":
        raise ConfigError(f"{where}.reward_type", f"unknown {reward!r}; physrover reads "
                          "Global, Difference, IndirectDifference")  # fmt: skip
    where = f"{where}.IndirectDifference"
    if params.get("type", "removal") != "removal":
        raise ConfigError(f"{where}.type", f"only 'removal' exists, got {params['type']!r}")
    assignment = params.get("assignment", "automatic")
    if assignment == "manual":
        fields.update(feedback="ID-manual", manual_removal=list(params.get("manual") or []))
        return fields
    if assignment != "automatic":
        raise ConfigError(f"{where}.assignment", f"automatic or manual, got {assignment!r}")
    automatic = params.get("automatic") or {}
    timescale = automatic.get("timescale", "trajectory")
    if timescale == "trajectory":
        fields["feedback"] = "ID"
    elif timescale == "timestep":
        credit = automatic.get("credit", "AllOrNothing")
        if credit not in LAB_STEP_CREDITS:
            raise ConfigError(f"{where}.automatic.credit", f"one of {', '.join(LAB_STEP_CREDITS)}"
                              f", got {credit!r}")  # fmt: skip
        fields["feedback"] = LAB_STEP_CREDITS[credit]
    else:
        raise ConfigError(f"{where}.automatic.timescale", f"trajectory or timestep, got "
                          f"{timescale!r}")  # fmt: skip
    return fields


def _sensor(agent: dict, where: str) -> dict[str, Any]:
    """The lidar table of one lab agent (module docstring)."""
    sensor = agent.get("sensor") or {}
    kind = sensor.get("type", "SmartLidar")
    if kind == "UavDistanceLidar":
        radius = float(get(agent, "observation_radius", where))
        return {"kind": "distances", "classes": ["uav"], "radius": radius, "blind": True,
                "observes": []}  # fmt: skip
    if kind not in ("SmartLidar", "RoverLidar"):
        raise ConfigError(f"{where}.sensor.type", "SmartLidar, RoverLidar or UavDistanceLidar,"
                          f" got {kind!r}")  # fmt: skip
    resolution = get(agent, "resolution", where)
    if 360 % resolution:
        raise ConfigError(f"{where}.resolution", f"must divide 360, got {resolution}")
    accum = sensor.get("accum_type", "average")
    measure = sensor.get("measurement_type", "inverse_distance_squared")
    for key, value, known in (("accum_type", accum, LAB_ACCUM),
                              ("measurement_type", measure, LAB_MEASURES)):  # fmt: skip
        if value not in known:
            raise ConfigError(f"{where}.sensor.{key}", f"one of {', '.join(known)}, got {value!r}")
    return {"kind": "lidar", "sectors": int(360 // resolution), "channels": "by-class",
            "bearing": "world", "radius": float(get(agent, "observation_radius", where)),
            "compose": LAB_ACCUM[accum], "measure": LAB_MEASURES[measure],
            "empty": float(sensor.get("default_value", -1.0)),
            "blind": kind == "RoverLidar",
            "observes": list(agent.get("observable_subtypes") or [])}  # fmt: skip


def _spawn(position: dict, where: str) -> tuple[str, Any]:
    """(rule, parameter) of a lab ``position`` table: fixed [x, y], a box or a circle."""
    rule = get(position, "spawn_rule", where)
    if rule == "fixed":
        return "fixed", [float(v) for v in get(position, "fixed", where)]
    if rule == "random_uniform":
        box = get(position, "random_uniform", where)
        return "box", [float(box[k]) for k in ("low_x", "high_x", "low_y", "high_y")]
    if rule == "random_circle":
        circle = get(position, "random_circle", where)
        return "circle", [*map(float, circle["center"]), float(circle["radius"])]
    raise ConfigError(f"{where}.spawn_rule", f"fixed, random_uniform or random_circle, got "
                      f"{rule!r}")  # fmt: skip


def _agent_class(kind: str, agents: list[dict], first: int, lab: dict) -> dict[str, Any]:
    """One ``[[agents]]`` table for lab agents ``agents`` (one type, tables equal but for a
    fixed spawn), the first at index ``first`` of the lab's ``kind`` list."""
    where = f"env.agents.{kind}[{first}]"
    agent = agents[0]
    network = lab.get("ccea", {}).get("network", {})
    speed = float(network.get(f"{kind[:-1]}_max_velocity", 1.0))
    map_x, map_y = (float(v) for v in lab["env"]["map_size"])
    bounds = agent.get("bounds") or {"low_x": 0.0, "high_x": map_x, "low_y": 0.0,
                                     "high_y": map_y}  # fmt: skip
    action = (agent.get("action") or {}).get("type", "dxdy")
    if action not in ("dxdy", "pick_uav"):
        raise ConfigError(f"{where}.action.type", f"dxdy or pick_uav, got {action!r}")
    policy = (agent.get("policy") or {}).get("type", "network")
    if policy not in ("network", "follow") or (policy == "follow" and action != "pick_uav"):
        raise ConfigError(f"{where}.policy.type", f"network, or follow with pick_uav, got "
                          f"{policy!r} with {action!r}")  # fmt: skip
    ours = {"dxdy": "world", "pick_uav": "follow" if policy == "follow" else "pick"}[action]
    table: dict[str, Any] = {
        "count": len(agents), "captures": kind == "rovers", "action": ours,
        "max_speed": speed, "sensor": _sensor(agent, where),
        "bounds": [float(bounds[k]) for k in ("low_x", "high_x", "low_y", "high_y")],
        **_feedback(agent, where),
    }  # fmt: skip
    if kind == "uavs":
        table["influence_radius"] = INFLUENCE_RADIUS
    if agent.get("needs_uav_to_move"):
        table["moves_with"] = ["uav"]
    if action == "pick_uav":
        table["picks"] = ["uav"]
    rule, value = _spawn(get(agent, "position", where), f"{where}.position")
    table["spawn"] = rule
    if rule == "fixed":
        table["spawn_positions"] = [_spawn(a["position"], where)[1] for a in agents]
    else:
        table["spawn_" + rule] = value
    return table


def _same_but_spawn(a: dict, b: dict) -> bool:
    """Whether two lab agent tables differ at most in a fixed spawn position."""
    a, b = copy.deepcopy(a), copy.deepcopy(b)
    for agent in (a, b):
        if agent.get("position", {}).get("spawn_rule") == "fixed":
            agent["position"].pop("fixed", None)
    return a == b


def _classes(lab: dict) -> list[dict[str, Any]]:
    """The ``[[agents]]`` tables of a lab config, rovers then UAVs (module docstring)."""
    tables = []
    for kind in ("rovers", "uavs"):
        agents = list(lab["env"]["agents"].get(kind) or [])
        groups: list[tuple[int, list[dict]]] = []
        for i, agent in enumerate(agents):
            if groups and _same_but_spawn(groups[-1][1][0], agent):
                groups[-1][1].append(agent)
            else:
                groups.append((i, [agent]))
        for j, (first, group) in enumerate(groups):
            name = kind[:-1] if len(groups) == 1 else f"{kind[:-1]}_{j + 1}"
            tables.append({"name": name, **_agent_class(kind, group, first, lab)})
    uavs = [t["name"] for t in tables if not t["captures"]]
    for table in tables:  # the UAV classes' names, now known
        for key in ("moves_with", "picks"):
            if key in table:
                table[key] = uavs
        if table["sensor"]["kind"] == "distances":
            table["sensor"]["classes"] = uavs
    return tables


def _pois(lab: dict, classes: list[dict]) -> tuple[list[dict[str, Any]], list[tuple[str, Any]]]:
    """The ``[[pois]]`` tables and each POI's lab spawn (:func:`_spawn`) of a lab config
    (module docstring)."""
    tables, positions = [], []
    pois = lab["env"]["pois"]
    # the lab's disappear_bool acts only in a rover's SmartLidar scan, on hidden POIs
    smart = [c["name"] for c in classes if c["captures"] and not c["sensor"]["blind"]]
    for kind in ("rover_pois", "hidden_pois"):
        for i, poi in enumerate(pois.get(kind) or []):
            where = f"env.pois.{kind}[{i}]"
            subtype = (poi.get("subtype") or "") if kind == "hidden_pois" else ""
            live = bool(smart) and kind == "hidden_pois"
            constraint = poi.get("constraint", "final")
            if constraint not in LAB_CONSTRAINTS:
                raise ConfigError(f"{where}.constraint", f"final or sequential, got "
                                  f"{constraint!r}")  # fmt: skip
            radius = float(poi.get("capture_radius", -1.0))
            table = {"value": float(get(poi, "value", where)),
                     "n_req": int(get(poi, "coupling", where)), "value_by": "distance",
                     "score_at": LAB_CONSTRAINTS[constraint],
                     "sense_radius": float(get(poi, "observation_radius", where))}  # fmt: skip
            if live and poi.get("disappear_bool"):
                table.update(disappear="visited", visit_radius=1.0, visited_by=smart)
            if radius == -1.0:
                table["capture_by"] = "sight"
            else:
                table.update(capture_by="radius-or-sight", capture_radius=radius)
            # a hidden POI with a subtype: only the UAVs that list it in their
            # observable_subtypes sense it (SmartLidar::scan; a rover POI's is never read)
            seen = [c["name"] for c in classes if not c["sensor"]["blind"]
                    and (kind == "rover_pois" or not c["captures"])
                    and (not subtype or subtype in c["sensor"]["observes"])]  # fmt: skip
            if subtype and not seen:
                raise ConfigError(f"{where}.subtype", f"no UAV observes {subtype!r}: "
                                  "physrover cannot hide a POI from every class")  # fmt: skip
            if seen and len(seen) < len(classes):  # nobody senses it: left to all (noted)
                table["visible_to"] = seen
            tables.append(table)
            positions.append(_spawn(get(poi, "position", where), f"{where}.position"))
    return tables, positions


def _scenario(
    spawns: list[tuple[str, Any]], pois: list[dict]
) -> tuple[dict[str, Any], tuple[float, float]]:
    """The ``[scenario]`` table of the POIs' lab spawns and the lab point that is
    physrover's origin: fixed POIs as they are (origin (0, 0)), POIs on one shared circle
    as ``ring-random`` around its centre, or else each POI by its own rule (``[[pois]]
    spawn``, written into ``pois``; origin (0, 0)), random ones drawn once per generation
    (the lab's harness)."""
    rules = {rule for rule, _ in spawns}
    if rules == {"fixed"}:  # agents' random spawns: drawn once per generation, as the lab's
        return {"kind": "explicit", "poi_positions": [v for _, v in spawns],
                "redraw": "generation"}, (0.0, 0.0)  # fmt: skip
    circles = {tuple(v) for rule, v in spawns if rule == "circle"}
    if rules == {"circle"} and len(circles) == 1:
        cx, cy, r = circles.pop()
        return {"kind": "ring-random", "poi_ring_radius": r, "ring_thickness": 0.0,
                "redraw": "generation"}, (cx, cy)  # fmt: skip
    placed = []  # where the explicit scenario puts each POI before its own rule moves it
    for table, (rule, value) in zip(pois, spawns, strict=True):
        table["spawn"] = rule
        if rule == "fixed":
            table["spawn_positions"] = [value]
            placed.append(value)
        elif rule == "box":
            table["spawn_box"] = value
            placed.append([(value[0] + value[1]) / 2, (value[2] + value[3]) / 2])
        else:
            table["spawn_circle"] = value
            placed.append([value[0] + value[2], value[1]])
    return {"kind": "explicit", "poi_positions": placed, "redraw": "generation"}, (0.0, 0.0)


def _shift(table: dict[str, Any], origin: tuple[float, float]) -> dict[str, Any]:
    """An ``[[agents]]`` table's positions, boxes and bounds with ``origin`` moved to (0, 0)."""
    ox, oy = origin
    box = lambda b: [b[0] - ox, b[1] - ox, b[2] - oy, b[3] - oy]  # noqa: E731
    out = dict(table, bounds=box(table["bounds"]))
    if "spawn_positions" in out:
        out["spawn_positions"] = [[x - ox, y - oy] for x, y in out["spawn_positions"]]
    if "spawn_box" in out:
        out["spawn_box"] = box(out["spawn_box"])
    if "spawn_circle" in out:
        x, y, r = out["spawn_circle"]
        out["spawn_circle"] = [x - ox, y - oy, r]
    return out


def lab_domain(lab: dict, steps: int | None = None) -> DomainConfig:
    """The :class:`~physrover.config.DomainConfig` of a lab config (a dict, as its YAML
    loads), over ``steps`` steps (default: its ``ccea.num_steps``); module docstring."""
    lab = copy.deepcopy(lab)
    if "env" not in lab:
        raise ConfigError("env", "missing: not a lab config")
    steps = steps if steps is not None else get(lab.get("ccea", {}), "num_steps", "ccea")
    agents = _classes(lab)
    pois, spawns = _pois(lab, agents)
    for table in agents:
        del table["sensor"]["blind"], table["sensor"]["observes"]
    if not pois:
        raise ConfigError("env.pois", "no POI: physrover needs at least one")
    scenario, origin = _scenario(spawns, pois)
    return DomainConfig.from_tables({
        "domain": {"steps": int(steps), "d_min": LAB_D_MIN},
        "scenario": scenario,
        "agents": [_shift(table, origin) for table in agents],
        "pois": pois,
    })  # fmt: skip


__all__ = ["INFLUENCE_RADIUS", "LAB_D_MIN", "get", "lab_domain"]
