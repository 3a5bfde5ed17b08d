"""The lidar sensor (``[sensor] kind = "lidar"``): the paper's sectors with the lab's later
choices of composition, measure, empty-sector value and bearing (AADILab/influence-shaping's
``lidar.hpp``).

Each rover sees the other rovers and the POIs within ``radius`` (true distance), in
``sectors`` equal sectors of bearing, two channels per sector (rovers, then POIs: 2n
observations, as the density sensor's). An object at distance d adds a *term*:

- ``measure = "inverse-square"``: ``num / max(d^2, d_min^2)`` (Eqs. 14-16; the lab's
  ``inverse_distance_squared`` with our ``d_min`` for its floor of 0.001 on d^2);
- ``measure = "linear"``: ``num (1 - d / radius)`` (the lab's
  ``one_minus_inverse_distance_over_observation_radius``; needs a finite radius);
- ``"inverse"``: ``num / max(d, d_min)`` (the lab's ``inverse_distance``, whose floor is
  0.001 where ours is ``d_min``); ``"exponential"``: ``num exp(-d)`` (its
  ``exponential_negative_distance``); ``"ratio"``: ``num d / radius`` (its
  ``distance_over_observation_radius``; a finite radius);

with ``num`` 1 for a rover and V_k for POI k. A sector's channel *composes* its terms:

- ``compose = "density"``: their sum (Eqs. 15-16; the lab's Density with ``sum``);
- ``"average"``: their mean (the lab's Density with ``average``, its default);
- ``"closest"``: the largest term (the lab's Closest, ``max_element``: the nearest object
  when the numerators are equal);

and a channel with no object in its sector reads ``empty`` (the lab: -1; 0 is the density
sensor's). ``bearing = "heading"`` measures sectors from dead behind, counter-clockwise
relative to the rover's heading (:func:`~physrover.domain.sensing.sectors.sector`, the
density sensor's convention); ``"world"`` from the +x axis whatever the heading, sector 0 =
[0, 360/n) degrees counter-clockwise (:func:`~physrover.domain.sensing.sectors.world_sector`).

``channels = "by-class"`` gives each agent class (``[[agents]]``) its own block of
sectors, then the POIs' (the lab's SmartLidar: ``[rovers | UAVs | POIs]``). A class senses
only the POIs visible to it (``[[pois]] visible_to``), each within its ``sense_radius``:
what a class senses is its :class:`SensingView`. No agent senses a POI that has left
sight (``[[pois]] disappear``, ``WorldState.gone``: :mod:`physrover.domain.sensing.vanish`).

Terms are added rovers by index, then POIs, in float64, as the density sensor adds them,
so ``lidar`` with ``compose = "density"``, ``bearing = "heading"``, ``empty = 0`` and the
inverse-square measure is the density sensor bit for bit (a test; up to float64 rounding
where the density sensor uses its grid, a finite radius and 100+ rovers). The compiled
step reads every class's lidar through one table (:mod:`physrover.domain.sensing.classes`);
in a large team a finite radius finds its neighbours from a grid, in index order, so the
readings are the all-pairs ones bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar, NamedTuple

import numpy as np

from physrover.config import check, check_choice
from physrover.core.compiled import jit, jit_inline
from physrover.domain.agents.classes import agent_classes, class_names
from physrover.domain.sensing.sectors import sector, world_sector
from physrover.domain.sensing.sensor import Sensor, register_sensor

COMPOSE = ("density", "average", "closest")
CHANNELS = ("agents-pois", "by-class")
MEASURES = ("inverse-square", "linear", "inverse", "exponential", "ratio")
BEARINGS = ("heading", "world")


@register_sensor
@dataclasses.dataclass(frozen=True)
class Lidar(Sensor):
    """Sectors of rovers and POIs with the lab's options (module docstring)."""

    kind: ClassVar[str] = "lidar"

    sectors: int = 4
    """Sectors of bearing: observations per rover are 2 x sectors (rovers, then POIs)."""
    radius: float = math.inf
    """Objects farther than this (world units) are not sensed; inf sees all."""
    compose: str = "density"
    """How a sector's terms make its reading: "density" (sum), "average" or "closest"."""
    measure: str = "inverse-square"
    """An object's term: "inverse-square" (num / max(d^2, d_min^2)), "linear"
    (num (1 - d / radius)), "inverse" (num / max(d, d_min)), "exponential" (num exp(-d)) or
    "ratio" (num d / radius)."""
    empty: float = 0.0
    """The reading of a sector with no object in it (the lab's default: -1)."""
    bearing: str = "heading"
    """Sectors relative to the rover's "heading" or fixed in the "world" frame."""
    channels: str = "agents-pois"
    """"agents-pois": [agents | POIs], 2 x sectors; "by-class": one block of sectors per
    agent class in [[agents]] order, then the POIs' (the lab's SmartLidar)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_at_least(1, "sectors")
        check(self.radius > 0, "radius", f"must be > 0 (inf: no limit), got {self.radius}")
        check_choice(self.compose, COMPOSE, "compose")
        check_choice(self.measure, MEASURES, "measure")
        check_choice(self.bearing, BEARINGS, "bearing")
        check_choice(self.channels, CHANNELS, "channels")
        check(self.measure not in ("linear", "ratio") or math.isfinite(self.radius), "measure",
              f'"{self.measure}" divides by the radius: give a finite radius')  # fmt: skip
        check(math.isfinite(self.empty), "empty", f"must be finite, got {self.empty}")

    @property
    def dim(self) -> int:
        return 2 * self.sectors

    def size(self, domain) -> int:
        """Observations per agent in ``domain`` (a DomainConfig): by class, a block per
        class and the POIs'."""
        if self.channels == "by-class":
            return (max(len(domain.agents), 1) + 1) * self.sectors
        return self.dim

    @property
    def low(self) -> float:
        """The observation space's lower bound: terms are >= 0, empty sectors read
        ``empty``."""
        return min(0.0, self.empty)

    def view(self, domain, c: int) -> SensingView:
        """What class ``c`` of ``domain`` (a DomainConfig; c = 0 without ``[[agents]]``)
        senses through this lidar: its channels and the POIs' rules (``[[pois]]``)."""
        n, k = self.sectors, domain.n_pois
        classes = domain.agents
        agent_class = agent_classes(domain)
        by_class = self.channels == "by-class"
        agent_base = (agent_class * n if by_class else np.zeros_like(agent_class)).astype(int)
        poi_base = max(len(classes), 1) * n if by_class else n
        name = class_names(domain)[c]
        pois = domain.pois
        if not pois:
            return SensingView(agent_base, poi_base, np.ones(k, bool), np.full(k, math.inf))
        visible = np.array([not p.visible_to or name in p.visible_to for p in pois])
        radius_sq = np.array([p.sense_radius**2 for p in pois], dtype=np.float64)
        return SensingView(agent_base, poi_base, visible, radius_sq)

    def observe(self, state, d_min: float, out: np.ndarray) -> None:
        """Every agent of ``state`` through this lidar, seeing everything (no classes, no
        POI rules): what a world without ``[[agents]]`` and ``[[pois]]`` senses."""
        n_agents, n_pois = state.cos_h.shape[1], state.poi_positions.shape[1]
        self.observe_class(state, d_min, out, SensingView.everything(n_agents, n_pois,
                                                                     self.sectors))  # fmt: skip

    def observe_class(self, state, d_min: float, out: np.ndarray, view: SensingView,
                      rows: slice | None = None) -> None:  # fmt: skip
        """:meth:`observe` as agents of one class see: the channels and POIs of ``view``,
        for the agents of ``rows`` only (a slice of the team, default all), into their rows
        of ``out`` (E, R, >= this sensor's size) and its first columns; the rest of ``out``
        is left as it was. The all-pairs kernel, one agent at a time (:func:`lidar_agent`)."""
        radius_sq = self.radius * self.radius if math.isfinite(self.radius) else math.inf
        first, stop, _ = (rows or slice(None)).indices(state.cos_h.shape[1])
        n_channels = view.poi_base + self.sectors  # the POIs' block is the last
        lidar_rows(state, d_min * d_min, self.sectors, radius_sq, COMPOSE.index(self.compose),
                   MEASURES.index(self.measure), self.empty, self.bearing == "world", *view,
                   first, stop, n_channels, out)  # fmt: skip


class SensingView(NamedTuple):
    """What the agents of one class sense (:meth:`Lidar.observe_class`): each agent's
    channel block, the POIs' block, which POIs the class sees and within what distance of
    each."""

    agent_base: np.ndarray
    """(R,) int64: the first channel of agent j's terms."""
    poi_base: int
    """The first channel of the POIs' terms."""
    visible: np.ndarray
    """(K,) bool: the POIs this class senses at all (``visible_to``)."""
    poi_radius_sq: np.ndarray
    """(K,) float64: a POI is sensed only within this squared distance (``sense_radius``)."""

    @classmethod
    def everything(cls, n_agents: int, n_pois: int, n_sectors: int) -> SensingView:
        """Every agent in one block, every POI visible at any distance."""
        return cls(np.zeros(n_agents, dtype=np.int64), n_sectors, np.ones(n_pois, bool),
                   np.full(n_pois, math.inf))  # fmt: skip


@jit_inline
def _add(acc, count, q, num, dist_sq, d_min_sq, radius_sq, measure, compose):
    """An object's term (``measure``: an index into :data:`MEASURES`) composed into channel
    q (a sum, or the largest term under "closest")."""
    if measure == 0:
        term = num / max(dist_sq, d_min_sq)  # Eq. 14
    elif measure == 1:
        term = num * (1.0 - math.sqrt(dist_sq) / math.sqrt(radius_sq))
    elif measure == 2:
        term = num / math.sqrt(max(dist_sq, d_min_sq))
    elif measure == 3:
        term = num * math.exp(-math.sqrt(dist_sq))
    else:
        term = num * (math.sqrt(dist_sq) / math.sqrt(radius_sq))
    if compose == 2:
        acc[q] = max(acc[q], term) if count[q] > 0 else term
    else:
        acc[q] += term
    count[q] += 1


@jit_inline
def lidar_agent(e, i, state, d_min_sq, n_sectors, radius_sq, compose, measure, empty, world,
                agent_base, poi_base, visible, poi_radius_sq, n_channels, candidates,
                n_candidates, acc, count, obs):  # fmt: skip
    """The lidar reading of agent i of team e into ``obs[e, i, :n_channels]``: the agents
    ``candidates[:n_candidates]`` (ascending: those a grid found near; None: every agent,
    ``n_candidates`` of them, compiled without the indirection),
    then every POI, each within its distance adding its term to its channel; ``compose``
    and ``measure`` index :data:`COMPOSE` and :data:`MEASURES`, ``radius_sq`` is inf for no
    radius, ``world`` the world-frame bearing (module docstring); ``agent_base`` to
    ``poi_radius_sq`` a :class:`SensingView`; a POI ``state.gone`` is not sensed; ``acc``,
    ``count`` (>= n_channels) scratch."""
    positions = state.rover_positions
    poi_positions, poi_values = state.poi_positions, state.poi_values
    c, s = state.cos_h[e, i], state.sin_h[e, i]
    xi, yi = positions[e, i, 0], positions[e, i, 1]
    for q in range(n_channels):
        acc[q] = 0.0
        count[q] = 0
    for m in range(n_candidates):  # the agents by index
        j = m if candidates is None else candidates[m]
        dx, dy = positions[e, j, 0] - xi, positions[e, j, 1] - yi
        dist_sq = dx * dx + dy * dy
        if dist_sq > radius_sq or j == i:
            continue
        if world:
            q = agent_base[j] + world_sector(dx, dy, n_sectors)
        else:
            q = agent_base[j] + sector(c * dx + s * dy, c * dy - s * dx, n_sectors)
        _add(acc, count, q, 1.0, dist_sq, d_min_sq, radius_sq, measure, compose)
    for k in range(poi_positions.shape[1]):  # then the POIs
        if not visible[k] or state.gone[e, k]:
            continue
        dx, dy = poi_positions[e, k, 0] - xi, poi_positions[e, k, 1] - yi
        dist_sq = dx * dx + dy * dy
        if dist_sq > min(radius_sq, poi_radius_sq[k]):
            continue
        if world:
            q = poi_base + world_sector(dx, dy, n_sectors)
        else:
            q = poi_base + sector(c * dx + s * dy, c * dy - s * dx, n_sectors)
        _add(acc, count, q, poi_values[e, k], dist_sq, d_min_sq, radius_sq, measure, compose)
    for q in range(n_channels):
        if count[q] == 0:
            obs[e, i, q] = empty
        elif compose == 1:
            obs[e, i, q] = acc[q] / count[q]
        else:
            obs[e, i, q] = acc[q]


@jit
def lidar_rows(state, d_min_sq, n_sectors, radius_sq, compose, measure, empty, world,
               agent_base, poi_base, visible, poi_radius_sq, first, stop, n_channels,
               obs):  # fmt: skip
    """:func:`lidar_agent` for agents ``first`` to ``stop - 1`` of every team of ``state``,
    each seeing every agent: ``obs[:, first:stop, :n_channels]``."""
    n_teams, n_rovers = state.cos_h.shape
    acc = np.zeros(n_channels)
    count = np.zeros(n_channels, dtype=np.int64)
    for e in range(n_teams):
        for i in range(first, stop):
            lidar_agent(e, i, state, d_min_sq, n_sectors, radius_sq, compose, measure, empty,
                        world, agent_base, poi_base, visible, poi_radius_sq, n_channels,
                        None, n_rovers, acc, count, obs)  # fmt: skip


__all__ = ["BEARINGS", "CHANNELS", "COMPOSE", "MEASURES", "Lidar", "SensingView", "lidar_agent",
           "lidar_rows"]  # fmt: skip
