"""What each agent class senses, as one table the compiled step reads.

A team senses through one of two compiled paths (:mod:`physrover.domain.plan` picks):

- the paper's density sensor for every rover (:func:`physrover.domain.sensing.density.sense_team`,
  vectorised), when there are no ``[[agents]]``, no POI hides and the sensor is the built-in
  :class:`~physrover.domain.sensing.density.Density`;
- otherwise :class:`ClassSensing`, a table with a row per class (in ``[[agents]]`` order;
  one row for the paper's team) of the lidar parameters and the class's
  :class:`~physrover.domain.sensing.lidar.SensingView`, which :func:`sense_classes` reads.
  A class's built-in lidar is its own row; a class's built-in density sensor is the lidar
  with ``compose = "density"``, the inverse-square measure, heading bearing and ``empty =
  0``, which is that sensor bit for bit (its all-pairs sums).

A class that senses distances to agents (:mod:`physrover.domain.sensing.distances`, the
lab's UavDistanceLidar) is a row too, read by :func:`sense_distances` instead.

A class whose sensor is neither built-in (a user's sensor, or a subclass of a built-in) is
left out of the table (``compiled`` False) and observed from Python after the step.

Each agent's observations fill its class's first ``n_channels[c]`` columns and the rest of
the world's (widest class's) row is 0.

Large teams: a class with a finite radius in a team of at least
:data:`LIDAR_GRID_MIN_POINTS` agents finds the agents within its radius from the cell list
of :func:`physrover.domain.broadphase.grid` (cells of the smallest such radius), and takes
them in index order (sorted by insertion: a few each), so its readings are the all-pairs
readings bit for bit; a class whose radius spans more than :data:`MAX_STENCIL` cells each
way (a UAV that sees the whole map) keeps the all-pairs loop.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from physrover.core.compiled import jit, jit_inline
from physrover.domain.agents.classes import class_rows, class_sensor
from physrover.domain.broadphase import drain_ascending, grid, mark
from physrover.domain.sensing.density import Density
from physrover.domain.sensing.distances import AgentDistances, sense_distances
from physrover.domain.sensing.lanes import Lanes, build_lanes, lanes_scratch, no_lanes, sense_lanes
from physrover.domain.sensing.lidar import COMPOSE, MEASURES, Lidar, SensingView, lidar_agent
from physrover.domain.sensing.sensor import sensor_size

LIDAR_GRID_MIN_POINTS = 64
"""Teams of at least this many agents find a finite-radius class's neighbours from a grid."""

MAX_STENCIL = 4
"""A class senses from the grid only if its radius spans at most this many cells each way."""

MAX_NEAR = 48
"""An agent with more agents than this in its cells (a crowd) scans every agent instead.
Measured (2026-12-03, EPYC Zen 3, ``benchmarks/configs/mixed200.toml`` packed into the
paper's spawn disc): the grid 3.4x slower than all-pairs without the cap, when the
candidates were sorted into index order by insertion (now a set of bits,
:func:`~physrover.domain.broadphase.drain_ascending`)."""


class ClassSensing(NamedTuple):
    """The sensing table of C classes of R agents and K POIs (module docstring); arrays
    indexed by class first."""

    d_min_sq: float
    """The bound of Eq. 14, squared (world units^2)."""
    first: np.ndarray
    """(C,) int64: the class's first agent."""
    stop: np.ndarray
    """(C,) int64: one past its last agent."""
    compiled: np.ndarray
    """(C,) bool: the table senses for this class (else Python does)."""
    n_sectors: np.ndarray
    """(C,) int64: sectors of bearing."""
    radius_sq: np.ndarray
    """(C,) float64: the sensing radius squared (inf: none)."""
    compose: np.ndarray
    """(C,) int64: index into :data:`~physrover.domain.sensing.lidar.COMPOSE`."""
    measure: np.ndarray
    """(C,) int64: index into :data:`~physrover.domain.sensing.lidar.MEASURES`."""
    empty: np.ndarray
    """(C,) float64: the reading of a sector with nothing in it."""
    world: np.ndarray
    """(C,) bool: sectors fixed in the world frame."""
    agent_base: np.ndarray
    """(C, R) int64: the first channel of agent j's terms, as class c sees it."""
    poi_base: np.ndarray
    """(C,) int64: the first channel of the POIs' terms."""
    visible: np.ndarray
    """(C, K) bool: the POIs class c senses at all."""
    poi_radius_sq: np.ndarray
    """(C, K) float64: within what squared distance."""
    n_channels: np.ndarray
    """(C,) int64: the class's observation size."""
    local: np.ndarray
    """(C,) bool: the class finds its neighbours from the grid."""
    distances: np.ndarray
    """(C,) bool: the class senses distances to agents
    (:mod:`physrover.domain.sensing.distances`), of the agents ``targets[c]`` within
    ``sqrt(radius_sq[c])``."""
    targets: np.ndarray
    """(C, R) bool: the agents a distances class measures."""
    as_density: np.ndarray
    """(C,) bool: the class's row reads as the density sensor (four sectors of heading, a
    sum of inverse squares): :func:`sense_classes` senses it with a copy of the kernel
    compiled with those choices as constants, and the lanes take only such rows."""
    cell: float
    """The grid's cell side (world units): the smallest radius of a local class; 0: none."""
    max_channels: int
    """The largest ``n_channels``."""
    lanes: Lanes
    """The whole team at once (:mod:`physrover.domain.sensing.lanes`) where every compiled
    class reads as the density sensor in one channel layout; else ``lanes.on`` is False."""

    @classmethod
    def build(cls, config) -> ClassSensing:
        """The table of ``config`` (a :class:`~physrover.config.DomainConfig`)."""
        rows = class_rows(config)
        n, k = config.n_rovers, config.n_pois
        table = {name: [] for name in cls._fields if name not in ("d_min_sq", "cell", "lanes",
                                                                   "max_channels",
                                                                   "as_density")}  # fmt: skip
        for c, row in enumerate(rows):
            sensor = class_sensor(config, c)
            kind = type(sensor)
            if kind is Lidar:
                view = sensor.view(config, c)
                lidar = sensor
            elif kind is AgentDistances:  # its radius; the other lidar fields unused
                lidar = Lidar(radius=sensor.radius)
                view = SensingView.everything(n, k, lidar.sectors)
            else:  # the density sensor as a lidar (module docstring); a placeholder row for
                # a Python sensor, which the table leaves out (compiled False)
                lidar = Lidar(sectors=sensor.sectors, radius=sensor.radius) if kind is Density \
                    else Lidar()  # fmt: skip
                view = SensingView.everything(n, k, lidar.sectors)
            radius_sq = lidar.radius**2 if math.isfinite(lidar.radius) else math.inf
            values = {
                "first": row.start, "stop": row.stop,
                "compiled": kind in (Lidar, Density, AgentDistances),
                "n_sectors": lidar.sectors, "radius_sq": radius_sq,
                "compose": COMPOSE.index(lidar.compose), "measure": MEASURES.index(lidar.measure),
                "empty": lidar.empty, "world": lidar.bearing == "world",
                "agent_base": view.agent_base, "poi_base": view.poi_base,
                "visible": view.visible, "poi_radius_sq": view.poi_radius_sq,
                "n_channels": sensor_size(sensor, config),
                "local": (n >= LIDAR_GRID_MIN_POINTS and math.isfinite(lidar.radius)
                          and kind is not AgentDistances),
                "distances": kind is AgentDistances,
                "targets": sensor.targets(config) if kind is AgentDistances
                else np.zeros(n, dtype=bool),
            }  # fmt: skip
            for name, value in values.items():
                table[name].append(value)
        radii = [math.sqrt(r) for r, local in zip(table["radius_sq"], table["local"],
                                                   strict=True) if local]  # fmt: skip
        cell = min(radii, default=0.0)
        table["local"] = [
            local and math.sqrt(r) <= MAX_STENCIL * cell
            for r, local in zip(table["radius_sq"], table["local"], strict=True)
        ]
        if not any(table["local"]):
            cell = 0.0
        dtypes = {
            "compiled": bool,
            "world": bool,
            "visible": bool,
            "local": bool,
            "distances": bool,
            "targets": bool,
            "radius_sq": float,
            "empty": float,
            "poi_radius_sq": float,
        }
        arrays = {name: np.array(v, dtype=dtypes.get(name, np.int64)) for name, v in table.items()}
        arrays["as_density"] = ((arrays["n_sectors"] == 4) & (arrays["compose"] == 0)
                                & (arrays["measure"] == 0) & ~arrays["world"])  # fmt: skip
        return cls(
            d_min_sq=float(config.d_min) ** 2,
            cell=float(cell),
            max_channels=int(max(table["n_channels"])),
            lanes=_lanes(arrays, k),
            **arrays,
        )


def _density_like(arrays: dict, c: int) -> bool:
    """Whether class c's row reads as the density sensor (``as_density``) with every agent
    in view: no grid, no distances."""
    return bool(arrays["as_density"][c] and not arrays["local"][c]
                and not arrays["distances"][c])  # fmt: skip


def _lanes(arrays: dict, n_pois: int) -> Lanes:
    """The team's :class:`~physrover.domain.sensing.lanes.Lanes` if every compiled class
    reads as the density sensor in one channel layout (the agents' blocks, the POIs' block
    and the size), else :func:`~physrover.domain.sensing.lanes.no_lanes`."""
    compiled = [c for c in range(len(arrays["first"])) if arrays["compiled"][c]]
    layouts = {(tuple(arrays["agent_base"][c]), int(arrays["poi_base"][c]),
                int(arrays["n_channels"][c])) for c in compiled}  # fmt: skip
    if not compiled or len(layouts) > 1 or not all(_density_like(arrays, c) for c in compiled):
        return no_lanes()
    fields = ("first", "stop", "radius_sq", "agent_base", "poi_base", "visible",
              "poi_radius_sq", "empty", "n_channels", "compiled")  # fmt: skip
    rows = [tuple(arrays[f][c] for f in fields) for c in range(len(arrays["first"]))]
    return build_lanes(rows, n_pois)


class SensingScratch(NamedTuple):
    """Per-call scratch of :func:`sense_classes` (:func:`sensing_scratch`)."""

    acc: np.ndarray
    count: np.ndarray
    near: np.ndarray
    lanes: np.ndarray


@jit
def sensing_scratch(sensing, n_agents):
    """Scratch of :func:`sense_classes` for teams of ``n_agents``."""
    lanes = lanes_scratch(sensing.lanes, n_agents) if sensing.lanes.on else np.zeros((1, 1))
    return SensingScratch(np.zeros(sensing.max_channels), np.zeros(sensing.max_channels,
                          np.int64), np.empty(n_agents, np.int64), lanes)  # fmt: skip


@jit
def _near(i, points, cells, nx, ny, starts, members, ordered, radius_sq, reach, marks, out):
    """The agents within ``radius_sq`` (squared, world units) of agent i, found in the
    (2 reach + 1)^2 cells around its cell, ascending, in ``out`` (through the empty set of
    bits ``marks``, left empty); returns how many (none for an agent in no cell), or -1
    if its cells hold more than :data:`MAX_NEAR` (a crowd: scanning every agent costs
    less). The distance test is :func:`~physrover.domain.sensing.lidar.lidar_agent`'s on
    the same numbers (``points``, the team's (R, 2) positions, and ``ordered``, the grid's
    copy of them), without a branch: whether a candidate is in range is a coin toss that
    the branch predictor cannot learn, and the lidar then sees only those in range."""
    cx, cy = cells[i, 0], cells[i, 1]
    n = 0
    if cx < 0:
        return n
    xi, yi = points[i, 0], points[i, 1]
    for x in range(max(cx - reach, 0), min(cx + reach, nx - 1) + 1):
        lo = x * ny + max(cy - reach, 0)
        hi = x * ny + min(cy + reach, ny - 1) + 1
        if n + starts[hi] - starts[lo] > MAX_NEAR:
            marks[:] = 0
            return -1
        for slot in range(starts[lo], starts[hi]):
            dx, dy = ordered[slot, 0] - xi, ordered[slot, 1] - yi
            mark(marks, members[slot], dx * dx + dy * dy <= radius_sq)
        n += starts[hi] - starts[lo]
    return drain_ascending(marks, out)


@jit
def _sense_near(e, state, sensing, acc, count, near, obs):
    """Every agent of team e in a class that finds its neighbours from the grid: those in
    the cells its radius reaches, or every agent for one in a crowd (:func:`_near`). (A
    copy compiled with the density sensor's choices as constants, as :func:`sense_classes`
    has, was no faster here: 2026-12-06, ``benchmarks/configs/mixed200.toml``.)"""
    n_agents, width = state.cos_h.shape[1], obs.shape[2]
    points = state.rover_positions[e]
    cells, nx, ny, starts, members, ordered = grid(points, sensing.cell)
    everyone = np.arange(n_agents)
    marks = np.zeros((n_agents + 63) // 64, np.uint64)
    for c in range(sensing.first.shape[0]):
        if not (sensing.compiled[c] and sensing.local[c]):
            continue
        n_channels, radius_sq = sensing.n_channels[c], sensing.radius_sq[c]
        reach = np.int64(math.ceil(math.sqrt(radius_sq) / sensing.cell))
        for i in range(sensing.first[c], sensing.stop[c]):
            n_near = _near(i, points, cells, nx, ny, starts, members, ordered, radius_sq,
                           reach, marks, near)  # fmt: skip
            lidar_agent(e, i, state, sensing.d_min_sq, sensing.n_sectors[c], radius_sq,
                        sensing.compose[c], sensing.measure[c], sensing.empty[c],
                        sensing.world[c], sensing.agent_base[c], sensing.poi_base[c],
                        sensing.visible[c], sensing.poi_radius_sq[c], n_channels,
                        near if n_near >= 0 else everyone,
                        n_near if n_near >= 0 else n_agents, acc, count, obs)  # fmt: skip
            for q in range(n_channels, width):
                obs[e, i, q] = 0.0


@jit_inline
def _sense_rows(e, c, state, sensing, n_sectors, compose, measure, world, acc, count, obs):
    """Every agent of class c in team e, seeing every agent, through its row of the table
    (:func:`lidar_agent`), the row read once; ``n_sectors`` to ``world`` the row's, passed
    apart so that a caller can pass constants (:func:`sense_classes`)."""
    n_agents, width, n_channels = state.cos_h.shape[1], obs.shape[2], sensing.n_channels[c]
    radius_sq, empty, d_min_sq = sensing.radius_sq[c], sensing.empty[c], sensing.d_min_sq
    agent_base, poi_base = sensing.agent_base[c], sensing.poi_base[c]
    visible, poi_radius_sq = sensing.visible[c], sensing.poi_radius_sq[c]
    for i in range(sensing.first[c], sensing.stop[c]):
        lidar_agent(e, i, state, d_min_sq, n_sectors, radius_sq, compose, measure, empty,
                    world, agent_base, poi_base, visible, poi_radius_sq, n_channels, None,
                    n_agents, acc, count, obs)  # fmt: skip
        for q in range(n_channels, width):
            obs[e, i, q] = 0.0


@jit
def _sense_all_pairs(e, c, state, sensing, acc, count, obs):
    """:func:`_sense_rows` with the row's sensing choices."""
    _sense_rows(e, c, state, sensing, sensing.n_sectors[c], sensing.compose[c],
                sensing.measure[c], sensing.world[c], acc, count, obs)  # fmt: skip


@jit
def _sense_as_density(e, c, state, sensing, acc, count, obs):
    """:func:`_sense_rows` for a row that reads as the density sensor does (four sectors of
    heading, a sum of inverse squares), compiled with those choices as constants."""
    _sense_rows(e, c, state, sensing, 4, 0, 0, False, acc, count, obs)


@jit_inline
def sense_classes(e, state, sensing, obs, scratch):
    """Every compiled class's readings for team ``e`` (:func:`lidar_agent`, the module
    docstring) into ``obs[e]`` (R, >= max_channels) float32, each row's columns past its
    class's size set to 0.

    A team whose compiled classes all read as the density sensor in one layout is sensed
    at once (:mod:`physrover.domain.sensing.lanes`). Otherwise a class reading as the
    density sensor (a sum of inverse squares in four sectors of heading) is compiled with
    those choices as constants: the general kernel branches on them for every object
    (2026-12-05, 50 teams of ``benchmarks/configs/mixed15.toml`` sensed 50 times: 4.3 ms
    before, 3.0 with the constants, 2.5 at once)."""
    acc, count, near, lanes = scratch
    if sensing.lanes.on:  # every compiled class at once
        sense_lanes(e, state, sensing.lanes, sensing.d_min_sq, lanes, obs)
        return
    if sensing.cell > 0.0:
        _sense_near(e, state, sensing, acc, count, near, obs)
    for c in range(sensing.first.shape[0]):
        if not sensing.compiled[c] or sensing.local[c]:
            continue
        if sensing.distances[c]:
            radius = math.sqrt(sensing.radius_sq[c])
            for i in range(sensing.first[c], sensing.stop[c]):
                for q in range(sense_distances(e, i, state.rover_positions, sensing.targets[c],
                                               radius, obs), obs.shape[2]):  # fmt: skip
                    obs[e, i, q] = 0.0
        elif sensing.as_density[c]:
            _sense_as_density(e, c, state, sensing, acc, count, obs)
        else:
            _sense_all_pairs(e, c, state, sensing, acc, count, obs)


__all__ = ["LIDAR_GRID_MIN_POINTS", "MAX_STENCIL", "ClassSensing", "SensingScratch",
           "sense_classes", "sensing_scratch"]  # fmt: skip
