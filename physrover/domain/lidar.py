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

with ``num`` 1 for a rover and V_k for POI k. A sector's channel *composes* its terms:

- ``compose = "density"``: their sum (Eqs. 15-16; the lab's Density with ``sum``);
- ``"average"``: their mean (the lab's Density with ``average``, its default);
- ``"closest"``: the largest term (the lab's Closest, ``max_element``: the nearest object
  when the numerators are equal);

and a channel with no object in its sector reads ``empty`` (the lab: -1; 0 is the density
sensor's). ``bearing = "heading"`` measures sectors from dead behind, counter-clockwise
relative to the rover's heading (:func:`~physrover.domain.sense_kernels.sector`, the density
sensor's convention); ``"world"`` from the +x axis whatever the heading, sector 0 =
[0, 360/n) degrees counter-clockwise (the lab's ``l2a``: ``atan2`` in degrees, +360 if
negative, ``int(angle / (360 / n))``, 360 -> 0).

Terms are added rovers by index, then POIs, in float64, as the density sensor adds them,
so ``lidar`` with ``compose = "density"``, ``bearing = "heading"``, ``empty = 0`` and the
inverse-square measure is the density sensor bit for bit (a test; up to float64 rounding
where the density sensor uses its grid, a finite radius and 100+ rovers). Cost: every pair
of a team is visited (R^2 per team and step, not compiled into the idealised step).
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from physrover.config import check, check_choice
from physrover.core.compiled import jit
from physrover.domain.sense_kernels import sector
from physrover.domain.sensors import Sensor, register_sensor

COMPOSE = ("density", "average", "closest")
MEASURES = ("inverse-square", "linear")
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
    """An object's term: "inverse-square" (num / max(d^2, d_min^2)) or "linear"
    (num (1 - d / radius))."""
    empty: float = 0.0
    """The reading of a sector with no object in it (the lab's default: -1)."""
    bearing: str = "heading"
    """Sectors relative to the rover's "heading" or fixed in the "world" frame."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_at_least(1, "sectors")
        check(self.radius > 0, "radius", f"must be > 0 (inf: no limit), got {self.radius}")
        check_choice(self.compose, COMPOSE, "compose")
        check_choice(self.measure, MEASURES, "measure")
        check_choice(self.bearing, BEARINGS, "bearing")
        check(self.measure != "linear" or math.isfinite(self.radius), "measure",
              '"linear" is 1 - d / radius: give a finite radius')  # fmt: skip
        check(math.isfinite(self.empty), "empty", f"must be finite, got {self.empty}")

    @property
    def dim(self) -> int:
        return 2 * self.sectors

    @property
    def low(self) -> float:
        """The observation space's lower bound: terms are >= 0, empty sectors read
        ``empty``."""
        return min(0.0, self.empty)

    def observe(self, state, d_min: float, out: np.ndarray) -> None:
        radius_sq = self.radius * self.radius if math.isfinite(self.radius) else math.inf
        lidar(state, d_min * d_min, self.sectors, radius_sq, COMPOSE.index(self.compose),
              MEASURES.index(self.measure), self.empty, self.bearing == "world", out)  # fmt: skip


@jit
def _world_sector(dx: float, dy: float, n_sectors: int) -> int:
    """The lab's ``l2a`` sector of an offset (dx, dy) in the world frame (module docstring)."""
    angle = math.degrees(math.atan2(dy, dx))
    if angle < 0.0:
        angle += 360.0
    q = np.int64(angle / (360.0 / n_sectors))
    return q if q < n_sectors else 0


@jit
def _add(acc, count, q, term, compose):
    """Compose ``term`` into channel q: a sum, or the largest term (``compose`` 2)."""
    if compose == 2:
        acc[q] = max(acc[q], term) if count[q] > 0 else term
    else:
        acc[q] += term
    count[q] += 1


@jit
def _term(num, dist_sq, d_min_sq, radius_sq, measure):
    if measure == 0:
        return num / max(dist_sq, d_min_sq)  # Eq. 14
    return num * (1.0 - math.sqrt(dist_sq) / math.sqrt(radius_sq))


@jit
def lidar(state, d_min_sq, n_sectors, radius_sq, compose, measure, empty, world, obs):
    """The lidar readings (E, R, 2 n_sectors) of every rover of ``state`` into ``obs``:
    ``compose`` and ``measure`` are indices into :data:`COMPOSE` and :data:`MEASURES`,
    ``radius_sq`` inf for no radius, ``world`` the world-frame bearing (module docstring)."""
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    poi_positions, poi_values = state.poi_positions, state.poi_values
    n_teams, n_rovers = cos_h.shape
    acc = np.zeros(2 * n_sectors)
    count = np.zeros(2 * n_sectors, dtype=np.int64)
    for e in range(n_teams):
        for i in range(n_rovers):
            c, s = cos_h[e, i], sin_h[e, i]
            xi, yi = positions[e, i, 0], positions[e, i, 1]
            acc[:] = 0.0
            count[:] = 0
            for j in range(n_rovers + poi_positions.shape[1]):  # rovers by index, then POIs
                if j == i:
                    continue
                if j < n_rovers:
                    dx, dy, num, base = positions[e, j, 0] - xi, positions[e, j, 1] - yi, 1.0, 0
                else:
                    k = j - n_rovers
                    dx, dy = poi_positions[e, k, 0] - xi, poi_positions[e, k, 1] - yi
                    num, base = poi_values[e, k], n_sectors
                dist_sq = dx * dx + dy * dy
                if dist_sq > radius_sq:
                    continue
                if world:
                    q = _world_sector(dx, dy, n_sectors)
                else:
                    q = sector(c * dx + s * dy, c * dy - s * dx, n_sectors)
                _add(acc, count, base + q, _term(num, dist_sq, d_min_sq, radius_sq, measure),
                     compose)  # fmt: skip
            for q in range(2 * n_sectors):
                if count[q] == 0:
                    obs[e, i, q] = empty
                elif compose == 1:
                    obs[e, i, q] = acc[q] / count[q]
                else:
                    obs[e, i, q] = acc[q]


__all__ = ["BEARINGS", "COMPOSE", "MEASURES", "Lidar", "lidar"]
