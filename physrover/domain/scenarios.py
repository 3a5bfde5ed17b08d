"""The scenario seam: the start state of every episode (POI layout and values, rover spawn).

A scenario is a frozen dataclass whose fields are its parameters (the ``[scenario]`` table,
``kind = "NAME"`` choosing the class) with one method, :meth:`Scenario.draw`. Built in:

- ``ring`` (the paper's, default): POIs evenly on a ring of radius ``poi_ring_radius``, the
  first at angle 0, the rest counter-clockwise; rovers uniform in a disc of radius
  ``spawn_radius`` at the origin, headings uniform in [-pi, pi).

A new scenario is a :class:`Scenario` subclass and one :func:`register_scenario` call, from
any module; its name then works in TOML (``[scenario] kind = "NAME"``) and on the command
line (``--set scenario=NAME``), or an instance is passed in code
(``RoverVectorEnv(50, scenario=MyScenario())``).

Random draws: team e draws from ``rngs[e]`` alone, so a team's start state depends only on
its own generator, and the same seeds give the same start states.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import ClassVar, NamedTuple

import numpy as np

from physrover.config import Component
from physrover.registry import SCENARIOS


class StartState(NamedTuple):
    """The start of an episode for E teams (arrays float64, team axis first)."""

    rover_positions: np.ndarray
    """(E, R, 2), world units."""
    rover_headings: np.ndarray
    """(E, R), radians."""
    poi_positions: np.ndarray
    """(E, K, 2), world units."""
    poi_values: np.ndarray
    """(E, K), positive."""


@dataclasses.dataclass(frozen=True)
class Scenario(Component):
    """Start states of episodes; see the module docstring. Subclasses are frozen dataclasses
    that set ``kind`` and implement :meth:`draw` and :meth:`extent`."""

    section: ClassVar[str] = "scenario"

    def draw(
        self, rngs: Sequence[np.random.Generator], n_rovers: int, poi_values: np.ndarray
    ) -> StartState:
        """The start state of one episode per generator in ``rngs`` (one per team), with
        ``n_rovers`` rovers and the POIs of ``poi_values`` (K,) (the domain's, in order)."""
        raise NotImplementedError

    def extent(self) -> float:
        """The radius, world units, of a disc at the origin holding every start position
        (rovers and POIs); the physical model spaces its teams by it, videos frame it."""
        raise NotImplementedError

    def spawn_extent(self) -> float:
        """The radius of a disc at the origin holding every rover's start position (walls
        must enclose it); by default :meth:`extent`."""
        return self.extent()

    def check_domain(self, domain) -> None:
        """Raise :class:`~physrover.config.ConfigError` if the scenario cannot serve
        ``domain`` (a :class:`~physrover.config.DomainConfig`); by default it can."""


def register_scenario(cls: type[Scenario], *, replace: bool = False) -> type[Scenario]:
    """Register the scenario class ``cls`` under ``cls.kind`` (usable as a decorator)."""
    return SCENARIOS.register_class(cls, Scenario, "kind", replace=replace)


def spawn_in_disc(
    rngs: Sequence[np.random.Generator], n_rovers: int, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """Rovers uniform in the disc of ``radius`` at the origin, headings uniform in [-pi, pi):
    (E, R, 2) positions and (E, R) headings, team e from three uniforms per rover of
    ``rngs[e]`` (radius, angle, heading)."""
    u = np.stack([rng.random((n_rovers, 3)) for rng in rngs])  # (E, R, 3)
    r = radius * np.sqrt(u[..., 0])
    angle = 2.0 * np.pi * u[..., 1]
    positions = np.stack([r * np.cos(angle), r * np.sin(angle)], axis=-1)
    return positions, 2.0 * np.pi * u[..., 2] - np.pi


def per_team(array: np.ndarray, n_teams: int) -> np.ndarray:
    """``array`` repeated along a new leading team axis (a copy, float64)."""
    return np.array(np.broadcast_to(array, (n_teams, *np.shape(array))), dtype=np.float64)


@register_scenario
@dataclasses.dataclass(frozen=True)
class Ring(Scenario):
    """The paper's: POIs evenly on a ring, rovers in a disc at its centre."""

    kind: ClassVar[str] = "ring"

    poi_ring_radius: float = 15.0
    """POIs lie evenly on a circle of this radius around the origin, world units."""
    spawn_radius: float = 1.5
    """Rovers start uniformly at random in a disc of this radius at the origin, world units."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_positive("poi_ring_radius", "spawn_radius")

    def poi_layout(self, n_pois: int) -> np.ndarray:
        """(K, 2): evenly on the ring, the first at angle 0, the rest counter-clockwise."""
        angles = 2.0 * np.pi * np.arange(n_pois) / n_pois
        return self.poi_ring_radius * np.stack([np.cos(angles), np.sin(angles)], -1)

    def draw(self, rngs, n_rovers, poi_values):
        positions, headings = spawn_in_disc(rngs, n_rovers, self.spawn_radius)
        n_teams = len(rngs)
        pois = per_team(self.poi_layout(len(poi_values)), n_teams)
        return StartState(positions, headings, pois, per_team(poi_values, n_teams))

    def extent(self) -> float:
        return max(self.poi_ring_radius, self.spawn_radius)

    def spawn_extent(self) -> float:
        return self.spawn_radius


__all__ = ["Ring", "Scenario", "StartState", "per_team", "register_scenario",
           "spawn_in_disc"]  # fmt: skip
