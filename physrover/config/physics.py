"""The physical motion model's configuration: ``[physics]`` (``motion = "physics"``,
:mod:`physrover.domain.motion.physics`)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from physrover.config.base import ConfigBase, check, check_choice, coerce

PER_ROVER = ("rover_radius", "rover_mass", "max_force", "max_torque", "max_speed")
"""The [physics] fields that take one number for every rover or a list of one per rover."""

INTEGRATORS = ("auto", "pymunk", "compiled")
"""Values of ``[physics] integrator`` (:class:`PhysicsConfig`)."""


@dataclasses.dataclass(frozen=True)
class PhysicsConfig(ConfigBase):
    """The physical motion model (``motion = "physics"``, :mod:`physrover.domain.motion.physics`).

    Time unit: one environment step; lengths in world units; masses in mass units. The
    fields of :data:`PER_ROVER` take one number (every rover) or a list of one per rover (a
    heterogeneous team; :meth:`per_rover`).
    """

    section: ClassVar[str] = "physics"

    collisions: bool = True
    """Rovers of a team collide with each other."""
    rover_radius: Any = 0.2
    """Radius of a rover's circular body, world units."""
    rover_mass: Any = 1.0
    """Mass of a rover, mass units; moment of inertia is that of a disc."""
    max_force: Any = 0.5
    """Largest drive force, mass x world units / step^2: from rest to speed 1 takes
    rover_mass / max_force steps."""
    max_torque: Any = 0.05
    """Largest steering torque, mass x world units^2 / step^2."""
    max_speed: Any = math.inf
    """Largest commanded speed, world units per step (the command's own limit is sqrt(2));
    the velocity setpoint is scaled down to it."""
    substeps: int = 4
    """Physics steps per environment step."""
    solver_iterations: int = 10
    """Iterations of pymunk's contact solver per physics step (contacts with walls and
    obstacles; rovers' contacts with each other are the compiled pass's)."""
    walls: bool = False
    """Square walls around each team's world."""
    wall_half_size: float = 30.0
    """Half the side of the walled square centred on the origin, world units."""
    integrator: str = "auto"
    """Who integrates the bodies: ``"auto"``, the compiled step in open space (no walls or
    obstacles: Chipmunk's semi-implicit Euler step of free bodies, the same arithmetic,
    bit-identical to pymunk's x86-64 wheels, which use no fused multiply-adds; tested) and
    pymunk whenever there is something static to hit; ``"pymunk"``, pymunk always (the
    reference; about twice as slow in open space); ``"compiled"``, the compiled step
    always, the rovers' contacts with walls and obstacles resolved by the compiled contact
    pass alone (without Chipmunk's contacts after it: the same overlaps in
    ``benchmarks/contacts.py`` at the default 4 substeps, different trajectories, a
    walled world ~2.8x faster)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        for name in PER_ROVER:
            value = getattr(self, name)
            if isinstance(value, np.ndarray):  # a per-rover array given in code
                value = value.tolist()
            if isinstance(value, (list, tuple)):
                value = tuple(coerce(name, float, v) for v in value)
                check(len(value) >= 1, name, "a list needs one value per rover")
            else:
                value = coerce(name, float, value)
            object.__setattr__(self, name, value)
            for v in value if isinstance(value, tuple) else (value,):
                ok = v > 0 and (math.isfinite(v) or name == "max_speed")
                check(ok, name, f"must be > 0, got {v}")
        self.check_positive("wall_half_size")
        self.check_at_least(1, "substeps", "solver_iterations")
        check_choice(self.integrator, INTEGRATORS, "integrator")

    def per_rover(self, name: str, n_rovers: int) -> np.ndarray:
        """(R,) float64: field ``name`` of :data:`PER_ROVER` for each rover."""
        value = getattr(self, name)
        return np.array(value if isinstance(value, tuple) else (value,) * n_rovers, dtype=float)

    def check_rovers(self, n_rovers: int) -> None:
        """ConfigError unless every per-rover list has ``n_rovers`` values."""
        for name in PER_ROVER:
            value = getattr(self, name)
            n = len(value) if isinstance(value, tuple) else n_rovers
            check(n == n_rovers, name, f"a list needs one value per rover ({n_rovers}), got {n}")


__all__ = ["INTEGRATORS", "PER_ROVER", "PhysicsConfig"]
