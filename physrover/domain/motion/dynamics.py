"""The dynamics seam: how actions move the rovers (``[domain] motion``).

A motion model is a :class:`Dynamics` subclass, built per world as ``cls(config, n_teams)``
(``config`` the :class:`~physrover.config.DomainConfig`), that writes the rover arrays of the
world's :class:`~physrover.domain.state.WorldState` (positions, headings and their cosines
and sines, velocities) and nothing else. Built in:

- ``ideal`` (:class:`Ideal`, the paper's kinematics, Section 4.1.2): the action (forward,
  left) in the rover's frame is the step's displacement, and the rover turns to face it.
  It brings its kernel (:mod:`physrover.domain.motion.ideal`), which the step moves the
  rovers with (:mod:`physrover.domain.step`).
- ``physics`` (:class:`physrover.domain.motion.physics.PhysicsMotion`): rigid bodies with mass,
  finite force and torque and optional collisions (stepped by pymunk, or in open space by
  the same arithmetic compiled), parameters in ``[physics]``.

A new model is a subclass and one :func:`register_dynamics` call; its name then works as
``motion = "NAME"``. Actions reach :meth:`Dynamics.step` checked (no NaN) and clipped to
[-1, 1], as float64; the compiled step then senses, scores and records the state the model
wrote (:mod:`physrover.domain.step`). Only the built-in :class:`Ideal` itself (not a
subclass, which may override :meth:`~Dynamics.step`) is moved inside the compiled step.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from physrover.core.registry import DYNAMICS
from physrover.domain.agents.roles import Roles
from physrover.domain.motion.ideal import heading_trig, move_team


class Dynamics:
    """A motion model for E teams; see the module docstring."""

    name: ClassVar[str] = ""
    """The name it is registered under (``motion = "NAME"``)."""
    obstacles: ClassVar[bool] = False
    """Whether the model makes rovers collide with the scenario's static obstacles; a
    scenario with obstacles under a model without them is a config error."""

    def __init__(self, config, n_teams: int):
        self.config = config
        self.n_teams = int(n_teams)

    def reset(self, state, teams: np.ndarray | None = None) -> None:
        """Start an episode from the start positions and headings in ``state``; may adjust
        them (the physical model pushes overlapping rovers apart). Must set ``cos_h``,
        ``sin_h`` and ``rover_velocities``; the default sets them (at rest). ``teams``, an
        (E,) bool mask: only those teams start again (a vector env's ``reset_mask``), the
        others keep their state; a model whose ``reset`` takes no ``teams`` cannot."""
        if teams is None:
            heading_trig(state.rover_headings, state.cos_h, state.sin_h)
        else:  # those teams' rows only: a moved team's cosines are its move's, not cos(h)
            cos_h, sin_h = state.cos_h[teams], state.sin_h[teams]
            heading_trig(state.rover_headings[teams], cos_h, sin_h)
            state.cos_h[teams], state.sin_h[teams] = cos_h, sin_h
        state.rover_velocities[slice(None) if teams is None else teams] = 0.0

    def step(self, state, actions: np.ndarray, teams: np.ndarray | None = None) -> None:
        """Move the rovers of ``state`` by one environment step under ``actions`` (E, R, 2),
        clipped to [-1, 1], float64; of the ``teams`` (an (E,) bool mask) only, if given
        (the others keep their state; a model whose ``step`` takes no ``teams`` cannot)."""
        raise NotImplementedError


def register_dynamics(cls: type[Dynamics], *, replace: bool = False) -> type[Dynamics]:
    """Register the motion model ``cls`` under ``cls.name`` (usable as a decorator)."""
    return DYNAMICS.register_class(cls, Dynamics, "name", replace=replace)


@register_dynamics
class Ideal(Dynamics):
    """The paper's kinematics (:func:`physrover.domain.motion.ideal.move_team`); the step
    moves the rovers with its kernel, so :meth:`step` runs only when a subclass's world
    calls it."""

    name: ClassVar[str] = "ideal"

    def __init__(self, config, n_teams: int):
        super().__init__(config, n_teams)
        self.roles = Roles.build(config)  # agent classes' speeds, frames, gates, bounds

    def step(self, state, actions: np.ndarray, teams: np.ndarray | None = None) -> None:
        record = np.empty(actions.shape, dtype=np.float32)
        free = np.ones(actions.shape[1], dtype=np.bool_)
        for e in range(actions.shape[0]):
            if teams is None or teams[e]:
                move_team(e, actions, state, record, True, self.roles, free)


def compiled_motion(dynamics: Dynamics) -> bool:
    """Whether the compiled step moves the rovers itself: the built-in idealised model, not a
    subclass of it (module docstring)."""
    return type(dynamics) is Ideal
