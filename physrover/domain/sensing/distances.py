"""The distances to some agents (``kind = "distances"``): the lab's ``UavDistanceLidar``
(AADILab/influence-shaping ``custom_env.py``), what its rovers that pick a UAV sense.

An agent reads one channel per agent of the sensor's ``classes`` (``[[agents]]`` class
names), in team order: ``d / radius`` where the distance d (world units) is within
``radius``, else -1 (the lab's "not seen"). Itself, where its own class is listed, reads 0.
The compiled step reads it through the classes' sensing table
(:mod:`physrover.domain.sensing.classes`, :func:`sense_distances`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from physrover.config import ConfigError, check
from physrover.core.compiled import jit_inline
from physrover.domain.sensing.sensor import Sensor, register_sensor


@register_sensor
@dataclasses.dataclass(frozen=True)
class AgentDistances(Sensor):
    """The distance to every agent of ``classes``, over ``radius`` (module docstring)."""

    kind: ClassVar[str] = "distances"

    classes: tuple[str, ...] = ()
    """The classes whose agents it measures (the lab's: its UAVs)."""
    radius: float = 5.0
    """Farther agents read -1, world units (the lab's observation radius)."""

    low: ClassVar[float] = -1.0
    high: ClassVar[float] = 1.0
    senses_pois: ClassVar[bool] = False
    """It senses no POI, so a POI hidden from its class changes nothing."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        check(bool(self.classes), "classes", "name the [[agents]] classes it measures")
        check(0 < self.radius < math.inf, "radius", f"must be finite and > 0, got {self.radius}")

    @property
    def dim(self) -> int:
        raise ConfigError("sensor", 'kind = "distances" senses [[agents]] classes: its size '
                          "is the domain's (size(domain))")  # fmt: skip

    def size(self, domain) -> int:
        """One channel per agent of ``classes`` in ``domain`` (a DomainConfig)."""
        names = [c.name for c in domain.agents]
        for name in self.classes:
            check(name in names, "sensor.classes", f"unknown class {name!r}; classes: "
                  f"{', '.join(names) or 'none ([[agents]] tables name them)'}")  # fmt: skip
        return sum(c.count for c in domain.agents if c.name in self.classes)

    def targets(self, domain) -> np.ndarray:
        """(R,) bool: the agents it measures."""
        return np.array([c.name in self.classes for c in domain.agents for _ in range(c.count)])


@jit_inline
def sense_distances(e, i, positions, targets, radius, obs):
    """Agent i of team e's readings (module docstring) into ``obs[e, i]``, from the (E, R,
    2) ``positions``, the (R,) bool ``targets`` and ``radius``; returns how many."""
    q = 0
    for j in range(positions.shape[1]):
        if targets[j]:
            dx = positions[e, j, 0] - positions[e, i, 0]
            dy = positions[e, j, 1] - positions[e, i, 1]
            d = math.sqrt(dx * dx + dy * dy)
            obs[e, i, q] = d / radius if d <= radius else -1.0
            q += 1
    return q


__all__ = ["AgentDistances", "sense_distances"]
