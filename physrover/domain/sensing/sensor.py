"""The sensor seam: what each agent observes (``[sensor]``, or a class's ``sensor``).

A sensor is a frozen dataclass whose fields are its parameters (the ``[sensor]`` table,
``kind = "NAME"`` choosing the class), with a size :attr:`Sensor.dim` and a method
:meth:`Sensor.observe` that writes the (E, R, dim) observations of a
:class:`~physrover.domain.state.WorldState`. The learners size their inputs from ``dim``
(or ``size(domain)`` where it depends on the domain, :func:`sensor_size`).

A new sensor is a :class:`Sensor` subclass and one :func:`register_sensor` call (or an
instance passed in code: ``RoverVectorEnv(50, sensor=MySensor())``). The built-in sensors
bring their kernels, which the compiled step calls (:mod:`physrover.domain.step`); a sensor
without one (a user's, or a subclass of a built-in, which may override ``observe``) is
called from Python after the compiled step, and the world says so once
(:mod:`physrover.domain.plan`).
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from physrover.config import Component
from physrover.core.registry import SENSORS


@dataclasses.dataclass(frozen=True)
class Sensor(Component):
    """What an agent observes; see the module docstring. Subclasses are frozen dataclasses
    that set ``kind`` and implement :attr:`dim` and :meth:`observe`."""

    section: ClassVar[str] = "sensor"

    @property
    def dim(self) -> int:
        """Observations per agent."""
        raise NotImplementedError

    def observe(self, state, d_min: float, out: np.ndarray) -> None:
        """Write the (E, R, dim) float32 observations of every agent of ``state`` (a
        :class:`~physrover.domain.state.WorldState`) into ``out``; ``d_min`` is the domain's
        distance bound (Eq. 14), world units."""
        raise NotImplementedError


def sensor_size(sensor, domain) -> int:
    """Observations per agent of ``sensor`` in ``domain``: its ``size(domain)`` where it
    depends on the domain (a lidar's channels by class), else its ``dim``."""
    size = getattr(sensor, "size", None)
    return int(size(domain)) if size is not None else int(sensor.dim)


def agent_obs_sizes(config) -> list[int]:
    """Each agent's observation size: its class's sensor's (the world pads to the widest)."""
    if not config.agents:
        return [sensor_size(config.sensor, config)] * config.n_rovers
    return [sensor_size(c.sensor or config.sensor, config) for c in config.agents
            for _ in range(c.count)]  # fmt: skip


def register_sensor(cls: type[Sensor], *, replace: bool = False) -> type[Sensor]:
    """Register the sensor class ``cls`` under ``cls.kind`` (usable as a decorator)."""
    return SENSORS.register_class(cls, Sensor, "kind", replace=replace)


__all__ = ["Sensor", "agent_obs_sizes", "register_sensor", "sensor_size"]
