"""The plan of the step: what each part of a world's step is, decided once per world.

A world's config chooses a motion model, agent classes, a sensor per class, POI rules and
a coupling; :func:`build_plan` turns them into a :class:`StepPlan`, the static arguments
of every kernel the step calls, which the one composition of the step
(:mod:`physrover.domain.step`) reads. A part that is None is compiled away: the paper's
domain (idealised motion, one class of rovers, the density sensor, the paper's POIs) is
``StepPlan(motion=Motion(roles=None), density=(...), classes=None, rules=None, ...)`` and
compiles to the paper's step alone.

Parts and their kernels:

- ``motion``: :class:`Motion` when the built-in idealised model moves the agents inside the
  step (:func:`~physrover.domain.motion.ideal.move_team`, with the classes'
  :class:`~physrover.domain.agents.roles.Roles`); None when a motion model is stepped
  before the compiled step (the physical model, compiled or with pymunk, or a user's);
- ``density``: the paper's sensor for the whole team (also for a team of classes that all
  sense with it), :func:`~physrover.domain.sensing.density.sense_team`'s ``(d_min^2,
  sectors, radius^2)``;
- ``classes``: otherwise, what each class senses
  (:class:`~physrover.domain.sensing.classes.ClassSensing`);
- ``rules``: the POIs' rules (:class:`~physrover.domain.scoring.rules.PoiRules`), None
  where every POI scores as the paper's; then ``counted`` (R,) bool marks the agents that
  count toward couplings where a class does not capture (None: every agent counts);
- ``failures``: when each agent fails (:class:`~physrover.domain.agents.failures.Failures`,
  drawn at every reset), None where no agent can fail;
- ``vanish``: the POIs' sight rules (:class:`~physrover.domain.sensing.vanish.Vanishing`),
  None where every POI stays in sight;
- the coupling ``n_req`` (K,), ``d_cap^2`` and the last scored step ``t_final``.

What has no kernel (a user's sensor, a subclass of a built-in part that may override its
Python method, a user's motion model) runs in Python around the compiled step:
:attr:`Plan.python_parts` names it, and the world warns once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from physrover.domain.agents.classes import class_rows, class_sensor, counted_agents
from physrover.domain.agents.failures import Failures, alive_at
from physrover.domain.agents.roles import Roles
from physrover.domain.motion.dynamics import compiled_motion
from physrover.domain.scoring.captures import last_scored_step
from physrover.domain.scoring.rules import PoiRules
from physrover.domain.sensing.classes import ClassSensing
from physrover.domain.sensing.density import Density
from physrover.domain.sensing.lidar import Lidar
from physrover.domain.sensing.sensor import agent_obs_sizes, sensor_size
from physrover.domain.sensing.vanish import Vanishing


class Motion(NamedTuple):
    """The idealised motion inside the step: the classes' roles (None: the paper's rovers)."""

    roles: Any


class StepPlan(NamedTuple):
    """The static arguments of the compiled step (module docstring)."""

    motion: Any
    """:class:`Motion`, or None when the motion model is stepped before the kernel."""
    density: Any
    """``(d_min^2, sectors, radius_sq)`` of the paper's sensor for every agent, or None."""
    classes: Any
    """:class:`~physrover.domain.sensing.classes.ClassSensing`, or None."""
    rules: Any
    """:class:`~physrover.domain.scoring.rules.PoiRules`, or None (the paper's POIs)."""
    counted: Any
    """(R,) bool: without rules, the agents that count toward couplings; None: all."""
    n_req: np.ndarray
    """(K,) int64: each POI's coupling."""
    d_cap_sq: float
    """The capture radius squared (Eq. 13), world units^2."""
    t_final: int
    """The last scored step."""
    failures: Any = None
    """:class:`~physrover.domain.agents.failures.Failures`, or None (no agent fails)."""
    vanish: Any = None
    """:class:`~physrover.domain.sensing.vanish.Vanishing`, or None (POIs stay in sight)."""


@dataclass(frozen=True)
class Plan:
    """A world's plan: the kernel's :class:`StepPlan` and what runs beside it in Python."""

    step: StepPlan
    obs_dim: int
    """Observations per agent: the widest class's."""
    python_sensors: tuple
    """(rows, sensor, view or None, size) of each class observed from Python."""

    def observe_in_python(self, state, d_min: float, obs: np.ndarray, t) -> None:
        """The classes whose sensor brings no kernel, observed from Python into their rows
        of ``obs`` (E, R, n_obs) (the columns past a class's size 0), from ``state`` at
        step ``t`` (an int, or each team's (E,)); a failed agent's stay 0."""
        for rows, sensor, view, size in self.python_sensors:
            if view is not None:  # a class-aware sensor (a lidar's subclass)
                obs[:, rows] = 0.0
                sensor.observe_class(state, d_min, obs, view, rows)
                continue
            scratch = np.zeros((*obs.shape[:2], size), dtype=np.float32)
            sensor.observe(state, d_min, scratch)
            obs[:, rows] = 0.0
            obs[:, rows, :size] = scratch[:, rows]
        if self.python_sensors and self.step.failures is not None:
            obs[~alive_at(self.step.failures.at, t)] = 0.0

    @property
    def python_parts(self) -> list[str]:
        """The parts that bring no kernel, by name (the world warns once about them)."""
        return [f"sensor {type(sensor).__name__}" for _, sensor, _, _ in self.python_sensors]


def _rules_needed(config) -> bool:
    """Whether any POI scores differently from the paper's (else the rules are compiled
    away: the paper's scoring is the rules' with every rule at its default, and a class
    that does not capture is the ``counted`` mask)."""
    if any(p.scored_by_rule or p.capture_by != "radius" for p in config.pois):
        return True
    radii = {p.capture_radius for p in config.pois}
    return bool(radii - {0.0, config.d_cap})


def build_plan(config, dynamics, n_teams: int) -> Plan:
    """The plan of a world of ``n_teams`` teams of ``config`` (a
    :class:`~physrover.config.DomainConfig`) moved by ``dynamics``."""
    motion = Motion(Roles.build(config)) if compiled_motion(dynamics) else None
    sensor = config.sensor
    by_class = bool(config.agents) or any(p.hides for p in config.pois)
    density = classes = None
    python_sensors = []
    sensors = [class_sensor(config, c) for c in range(max(len(config.agents), 1))]
    if type(sensor) is Density and all(s == sensor for s in sensors) and not any(
            p.hides for p in config.pois):  # fmt: skip
        # every class senses with the paper's sensor: its vectorised kernel for the whole
        # team, the class table's readings bit for bit (tests/test_agent_classes.py)
        density = sensor.kernel_arguments(config.d_min)
    elif by_class or type(sensor) is Lidar:
        classes = ClassSensing.build(config)
        for c, rows in enumerate(class_rows(config)):
            if not classes.compiled[c]:
                own = class_sensor(config, c)
                view = own.view(config, c) if hasattr(own, "view") else None
                python_sensors.append((rows, own, view, sensor_size(own, config)))
    else:  # the whole team's sensor has no kernel
        python_sensors.append((slice(0, config.n_rovers), sensor, None,
                               sensor_size(sensor, config)))  # fmt: skip
    rules = PoiRules.build(config, n_teams, always=True) if _rules_needed(config) else None
    counted = counted_agents(config)
    counted = None if rules is not None or counted.all() else counted
    step = StepPlan(motion, density, classes, rules, counted,
                    np.array(config.n_req_per_poi, dtype=np.int64), float(config.d_cap) ** 2,
                    int(last_scored_step(config)), Failures.build(config, n_teams),
                    Vanishing.build(config))  # fmt: skip
    return Plan(step, max(agent_obs_sizes(config)), tuple(python_sensors))


__all__ = ["Motion", "Plan", "StepPlan", "build_plan"]
