"""The sensor seam: what each rover observes, and the paper's sensor (Eqs. 14-16).

A sensor is a frozen dataclass whose fields are its parameters (the ``[sensor]`` table,
``kind = "NAME"`` choosing the class), with a size :attr:`Sensor.dim` and a method
:meth:`Sensor.observe` that writes the (E, R, dim) observations of a
:class:`~physrover.domain.state.WorldState`. The learners size their inputs from ``dim``.
A new sensor is a :class:`Sensor` subclass and one :func:`register_sensor` call (or an
instance passed in code: ``RoverVectorEnv(50, sensor=MySensor())``). The world calls
``observe`` after every move; the built-in sensor is instead compiled into the idealised
step (``fused``), so that step stays one compiled call.

The density sensor (``kind = "density"``, the paper's)
-----------------------------------------------------
With the default four sectors (quadrants) each rover senses an 8-vector (the order of the
lab's rover-domain code):

- components 0-3: ``s_rover,q = sum_{j in J_q} 1 / delta_ij^2`` over the *other* rovers j of
  the team in quadrant q (Eq. 15);
- components 4-7: ``s_poi,q = sum_{k in K_q} V_k / delta_ik^2`` over the POIs k in quadrant
  q (Eq. 16);

with ``delta = max(||p_i - p_j||, d_min)`` the bounded distance of Eq. 14. With ``sectors
= n`` (the lab's ``n_observation_sections``) the same sums run over n equal sectors of
bearing, 2n observations, sector 0 starting dead behind and counting counter-clockwise;
with a finite ``radius`` an object farther than it (its true distance, before the d_min
bound) is left out of every sum. The compiled implementation is
:func:`physrover.domain.kernels.sense`.

Quadrant convention (the one of the paper's lab's rover-domain code)
--------------------------------------------------------------------
The bearing ``b`` of an object is measured counter-clockwise from the rover's heading and
wrapped to ``[-pi, pi)``; the quadrant is ``q = floor((b + pi) / (pi / 2))``:

====  ==============  ====================
 q    name            bearings
====  ==============  ====================
 0    behind-right    [-180 deg, -90 deg)
 1    front-right     [-90 deg, 0)
 2    front-left      [0, 90 deg)
 3    behind-left     [90 deg, 180 deg)
====  ==============  ====================

A bearing on a boundary goes to the quadrant that starts there (dead ahead -> 2, dead
right -> 1, dead left -> 3, dead behind -> 0). The bearing is read from the object's offset
``(f, l)`` in the rover's frame (``f`` forward, ``l`` left) as ``atan2(l, f)``, so an object
at the rover's own position (offset 0) has bearing 0 and lies in quadrant 2. The code uses
the signs of ``f`` and ``l`` instead of ``atan2``: the same answer, exact on the boundaries.
Other sector counts use ``floor((atan2(l, f) + pi) n / (2 pi))`` with a bearing of exactly
pi sent to sector 0: the same rule, up to atan2's rounding on a boundary.

The lab's code computes ``floor((atan2(l, f) + pi) / (2 pi) * 4)`` clipped to 0-3, which
agrees except for signed zeros: dead behind with ``l = +0`` (what its arithmetic gives for
heading 0) is its quadrant 3 (here 0), and a coincident object is its quadrant 3 when the
heading's cosine and sine are both negative (here always 2).
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from physrover.config import Component, check
from physrover.core.compiled import dims
from physrover.core.registry import SENSORS
from physrover.domain.kernels import Fused, sense


@dataclasses.dataclass(frozen=True)
class Sensor(Component):
    """What a rover observes; see the module docstring. Subclasses are frozen dataclasses
    that set ``kind`` and implement :attr:`dim` and :meth:`observe`."""

    section: ClassVar[str] = "sensor"
    fused: ClassVar[bool] = False
    """True only for sensors compiled into the idealised step kernel (the built-in one)."""

    @property
    def dim(self) -> int:
        """Observations per rover."""
        raise NotImplementedError

    def observe(self, state, d_min: float, out: np.ndarray) -> None:
        """Write the (E, R, dim) float32 observations of every rover of ``state`` (a
        :class:`~physrover.domain.state.WorldState`) into ``out``; ``d_min`` is the domain's
        distance bound (Eq. 14), world units."""
        raise NotImplementedError


def sensor_size(sensor, domain) -> int:
    """Observations per agent of ``sensor`` in ``domain``: its ``size(domain)`` where it
    depends on the domain (a lidar's channels by class), else its ``dim``."""
    size = getattr(sensor, "size", None)
    return int(size(domain)) if size is not None else int(sensor.dim)


def register_sensor(cls: type[Sensor], *, replace: bool = False) -> type[Sensor]:
    """Register the sensor class ``cls`` under ``cls.kind`` (usable as a decorator)."""
    return SENSORS.register_class(cls, Sensor, "kind", replace=replace)


@register_sensor
@dataclasses.dataclass(frozen=True)
class Density(Fused, Sensor, fused=True):
    """The paper's sensor: rover and POI densities by sector of bearing (Eqs. 14-16), four
    quadrants by default (the lab's n_observation_sections), optionally blind beyond a radius
    (zerbeln/RoverDomain's observation radius)."""

    kind: ClassVar[str] = "density"

    sectors: int = 4
    """Sectors of bearing: observations per rover are 2 x sectors (rovers, then POIs)."""
    radius: float = math.inf
    """Objects farther than this (world units) are not sensed; inf (default) sees all."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_at_least(1, "sectors")
        check(self.radius > 0, "radius", f"must be > 0 (inf: no limit), got {self.radius}")

    @property
    def dim(self) -> int:
        return 2 * self.sectors

    def kernel_arguments(self, d_min: float) -> tuple:
        """``(d_min, sectors, radius_sq)`` as :func:`physrover.domain.kernels.sense` takes
        them (the sector count as a size tuple, no radius as None)."""
        radius_sq = self.radius * self.radius if math.isfinite(self.radius) else None
        return d_min, dims(self.sectors), radius_sq

    def observe(self, state, d_min: float, out: np.ndarray) -> None:
        sense(state, *self.kernel_arguments(d_min), out)


# Run directories written while this sensor was named "quadrants" (before sector counts)
# still load: the name is an alias of the density sensor with its default four sectors.
SENSORS.register("quadrants", Density, alias=True)
