"""The scenario seam: the start state of every episode (POI layout and values, rover spawn).

A scenario is a frozen dataclass whose fields are its parameters (the ``[scenario]`` table,
``kind = "NAME"`` choosing the class) with one method, :meth:`Scenario.draw`. Built in:

- ``ring`` (the paper's, default): POIs evenly on a ring of radius ``poi_ring_radius``, the
  first at angle 0, the rest counter-clockwise; rovers uniform in a disc of radius
  ``spawn_radius`` at the origin, headings uniform in [-pi, pi);
- ``ring-random`` (the lab's experiment harness): POI angles uniform in [-pi, pi), radii
  uniform in [(1 - ring_thickness) poi_ring_radius, poi_ring_radius]; rovers as ``ring``;
- ``uniform``: POIs uniform in the square of half side ``half_size`` at the origin, at least
  ``min_separation`` apart; rovers as ``ring``;
- ``explicit``: POI positions listed in the table (values are [domain] ``poi_values``),
  optionally the rovers' positions and headings (else drawn as ``ring``) and static
  obstacles (discs, boxes, segments: :mod:`physrover.domain.obstacles`).

Redraws (``redraw``, every scenario):

- ``"episode"`` (default): every episode of every team starts from its own draw;
- ``"generation"``: one draw per reset of the world, shared by all its teams but the last
  ``RoverWorld.fresh_teams`` (the CCEA's evaluation episodes, which draw their own): the
  lab's harness, which draws one start state per generation for all training episodes
  and a fresh one for evaluation (it evaluates one; the CCEA here evaluates
  ``eval_episodes`` fresh ones);
- ``"never"``: every episode of every team starts from one draw made from a generator
  seeded with ``layout_seed``, the same in every run (so also across learning seeds).

Under ``"episode"`` and ``"generation"`` the teams' generators advance identically (every
team draws, shared draws are discarded), so a team's later episodes do not depend on the
mode of earlier ones.

A new scenario is a :class:`Scenario` subclass and one :func:`register_scenario` call, from
any module; its name then works in TOML (``[scenario] kind = "NAME"``) and on the command
line (``--set scenario=NAME``), or an instance is passed in code
(``RoverVectorEnv(50, scenario=MyScenario())``).

Random draws: team e draws from ``rngs[e]`` alone, so a team's start state depends only on
its own generator, and the same seeds give the same start states.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import ClassVar, NamedTuple

import numpy as np

from physrover.config import Component, check, check_choice
from physrover.core.registry import SCENARIOS
from physrover.domain.layouts import uniform_layouts
from physrover.domain.obstacles import capsules, check_obstacles, reach


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


REDRAWS = ("episode", "generation", "never")


@dataclasses.dataclass(frozen=True)
class Scenario(Component):
    """Start states of episodes; see the module docstring. Subclasses are frozen dataclasses
    that set ``kind`` and implement :meth:`draw` and :meth:`extent` (and may check their
    parameters in :meth:`validate`)."""

    section: ClassVar[str] = "scenario"

    redraw: str = "episode"
    """How often start states are drawn: "episode", "generation" or "never" (module doc)."""
    layout_seed: int = 0
    """Seed of the one start state under redraw = "never"."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        check_choice(self.redraw, REDRAWS, "redraw")
        self.check_at_least(0, "layout_seed")
        self.validate()

    def validate(self) -> None:
        """Raise :class:`~physrover.config.ConfigError` for bad parameters (by default none)."""

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

    def obstacles(self) -> np.ndarray:
        """(M, 3) static discs ``[x, y, radius]`` in world units, the same in every episode
        and team (by default none). The physical model makes them static bodies that rovers
        collide with; under the idealised kinematics (the paper's, which has none) they are a
        config error; sensors find them in ``WorldState.obstacles``
        (:mod:`physrover.domain.obstacles`)."""
        return np.zeros((0, 3))

    def boxes(self) -> np.ndarray:
        """(B, 5) static boxes ``[x, y, half_width, half_height, angle]`` (world units,
        radians), as :meth:`obstacles` (by default none)."""
        return np.zeros((0, 5))

    def segments(self) -> np.ndarray:
        """(S, 5) static segments ``[ax, ay, bx, by, radius]`` (walls of thickness
        2 radius with round ends, world units), as :meth:`obstacles` (by default none)."""
        return np.zeros((0, 5))

    def obstacle_capsules(self) -> np.ndarray:
        """(M, 5) every obstacle as capsules (:func:`physrover.domain.obstacles.capsules`)."""
        return capsules(self.obstacles(), self.boxes(), self.segments())


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


MIN_SPAWN_DENSITY = 1e-6
"""The smallest ``spawn_density`` other than 0 (off): a team of R then spawns within
``sqrt(R / (pi 1e-6))``, ~564 sqrt(R) world units; smaller would overflow to an infinite
disc."""


@dataclasses.dataclass(frozen=True)
class SpawnDisc(Scenario):
    """A scenario whose rovers start in the spawn disc (:func:`spawn_in_disc`); subclasses
    place the POIs (:meth:`pois`, drawn after the rovers from each team's generator)."""

    spawn_radius: float = 1.5
    """Rovers start uniformly at random in a disc of this radius at the origin, world units."""
    spawn_density: float = 0.0
    """Large teams (beyond the paper): at most this many rovers per square world unit of the
    spawn disc, which grows to radius ``sqrt(R / (pi spawn_density))`` where
    ``spawn_radius`` would hold more (0: off, the disc is ``spawn_radius`` at any R). The
    paper's 15 rovers in radius 1.5 are 2.1 per unit^2; 0.2 spreads 1000 rovers over
    radius 40 (2.5% of the disc under rovers of radius 0.2)."""

    def validate(self) -> None:
        self.check_positive("spawn_radius")
        density = self.spawn_density
        check(density == 0 or (MIN_SPAWN_DENSITY <= density and math.isfinite(density)),
              "spawn_density", f"must be 0 (off) or >= {MIN_SPAWN_DENSITY} (the spawn disc "
              f"grows as sqrt(R / (pi spawn_density))), got {density}")  # fmt: skip

    def disc_radius(self, n_rovers: int) -> float:
        """The spawn disc's radius for a team of ``n_rovers`` (see ``spawn_density``)."""
        if self.spawn_density <= 0:
            return self.spawn_radius
        return max(self.spawn_radius, math.sqrt(n_rovers / (math.pi * self.spawn_density)))

    def pois(self, rngs: Sequence[np.random.Generator], n_pois: int) -> np.ndarray:
        """(E, K, 2) POI positions, world units."""
        raise NotImplementedError

    def poi_extent(self) -> float:
        """The radius of a disc at the origin holding every POI, world units."""
        raise NotImplementedError

    def draw(self, rngs, n_rovers, poi_values):
        positions, headings = spawn_in_disc(rngs, n_rovers, self.disc_radius(n_rovers))
        pois = self.pois(rngs, len(poi_values))
        return StartState(positions, headings, pois, per_team(poi_values, len(rngs)))

    def extent(self) -> float:
        return max(self.poi_extent(), self.spawn_radius)

    def spawn_extent(self) -> float:
        return self.spawn_radius

    def extent_for(self, n_rovers: int) -> float:
        """:meth:`extent` for a team of ``n_rovers`` (the disc may grow with the team)."""
        return max(self.poi_extent(), self.disc_radius(n_rovers))

    def spawn_extent_for(self, n_rovers: int) -> float:
        return self.disc_radius(n_rovers)


@register_scenario
@dataclasses.dataclass(frozen=True)
class Ring(SpawnDisc):
    """The paper's: POIs evenly on a ring, rovers in a disc at its centre."""

    kind: ClassVar[str] = "ring"

    poi_ring_radius: float = 15.0
    """POIs lie evenly on a circle of this radius around the origin, world units."""

    def validate(self) -> None:
        super().validate()
        self.check_positive("poi_ring_radius")

    def poi_layout(self, n_pois: int) -> np.ndarray:
        """(K, 2): evenly on the ring, the first at angle 0, the rest counter-clockwise."""
        angles = 2.0 * np.pi * np.arange(n_pois) / n_pois
        return self.poi_ring_radius * np.stack([np.cos(angles), np.sin(angles)], -1)

    def pois(self, rngs, n_pois):
        return per_team(self.poi_layout(n_pois), len(rngs))

    def poi_extent(self) -> float:
        return self.poi_ring_radius


@register_scenario
@dataclasses.dataclass(frozen=True)
class RingRandom(Ring):
    """POIs at random angles on a ring (the lab's harness); rovers in the spawn disc. The
    ring's radius ``poi_ring_radius`` is its outer radius."""

    kind: ClassVar[str] = "ring-random"

    ring_thickness: float = 0.0
    """Fraction of the radius the ring extends inwards: radii uniform in
    [(1 - ring_thickness) poi_ring_radius, poi_ring_radius] (the lab's poi_init_thickness)."""

    def validate(self) -> None:
        super().validate()
        self.check_unit("ring_thickness")

    def pois(self, rngs, n_pois):
        u = np.stack([rng.random((n_pois, 2)) for rng in rngs])  # (E, K, 2): angle, radius
        angle = 2.0 * np.pi * u[..., 0] - np.pi
        inner = (1.0 - self.ring_thickness) * self.poi_ring_radius
        radius = inner + (self.poi_ring_radius - inner) * u[..., 1]
        return np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)


@register_scenario
@dataclasses.dataclass(frozen=True)
class Uniform(SpawnDisc):
    """POIs uniform in a square, at least ``min_separation`` apart; rovers in the spawn disc."""

    kind: ClassVar[str] = "uniform"

    half_size: float = 15.0
    """Half the side of the square centred on the origin, world units."""
    min_separation: float = 0.0
    """Smallest distance between two POIs, world units (redrawn until it holds)."""

    MAX_TRIES: ClassVar[int] = 200

    def validate(self) -> None:
        super().validate()
        self.check_positive("half_size")
        self.check_at_least(0.0, "min_separation")

    def check_domain(self, domain) -> None:
        # Random sequential placement jams when discs of diameter min_separation cover
        # ~55% of the (padded) square: keep them within 40%, where draws rarely fail.
        k, side = domain.n_pois, 2.0 * self.half_size + self.min_separation
        check(
            k * (self.min_separation / 2) ** 2 * np.pi <= 0.4 * side * side,
            "min_separation",
            f"{k} POIs cannot be drawn {self.min_separation} apart in a square of half side "
            f"{self.half_size} (keep their discs within 40% of the square's area)",
        )

    def pois(self, rngs, n_pois):
        """Each POI redrawn until it is min_separation from those before it; after
        ``MAX_TRIES`` failed draws of one POI the whole layout starts again (a bad early
        placement can leave no room), up to ``MAX_TRIES`` times
        (:func:`~physrover.domain.layouts.uniform_layouts`, compiled)."""
        return uniform_layouts(rngs, n_pois, self.half_size, self.min_separation, self.MAX_TRIES)

    def poi_extent(self) -> float:
        return self.half_size * np.sqrt(2.0)


@register_scenario
@dataclasses.dataclass(frozen=True)
class Explicit(Scenario):
    """POI positions (and optionally the rovers' start) written in the config."""

    kind: ClassVar[str] = "explicit"

    poi_positions: tuple[tuple[float, ...], ...] = ((15.0, 0.0), (0.0, 15.0), (-15.0, 0.0),
                                                    (0.0, -15.0))  # fmt: skip
    """[[x, y], ...] of every POI, world units, in the order of [domain] poi_values."""
    rover_positions: tuple[tuple[float, ...], ...] = ()
    """[[x, y], ...] of every rover, world units; empty: drawn in the spawn disc."""
    rover_headings: tuple[float, ...] = ()
    """Every rover's heading, radians; empty: drawn uniformly in [-pi, pi)."""
    spawn_radius: float = 1.5
    """The spawn disc's radius when rover_positions is empty, world units."""
    obstacle_discs: tuple[tuple[float, ...], ...] = ()
    """[[x, y, radius], ...] static discs, world units (physical motion only)."""
    obstacle_boxes: tuple[tuple[float, ...], ...] = ()
    """[[x, y, half_width, half_height, angle], ...] static boxes, world units and radians."""
    obstacle_segments: tuple[tuple[float, ...], ...] = ()
    """[[ax, ay, bx, by, radius], ...] static segments (walls 2 radius thick), world units."""

    def validate(self) -> None:
        self.check_positive("spawn_radius")
        for name in ("poi_positions", "rover_positions"):
            for p in getattr(self, name):
                check(len(p) == 2 and all(np.isfinite(p)), name,
                      f"every position must be a finite [x, y], got {list(p)}")  # fmt: skip
        check(all(np.isfinite(self.rover_headings)), "rover_headings", "must be finite")
        check_obstacles(self.obstacle_discs, self.obstacle_boxes, self.obstacle_segments, check)

    def obstacles(self) -> np.ndarray:
        return np.array(self.obstacle_discs, dtype=np.float64).reshape(-1, 3)

    def boxes(self) -> np.ndarray:
        return np.array(self.obstacle_boxes, dtype=np.float64).reshape(-1, 5)

    def segments(self) -> np.ndarray:
        return np.array(self.obstacle_segments, dtype=np.float64).reshape(-1, 5)

    def check_domain(self, domain) -> None:
        check(
            len(self.poi_positions) == domain.n_pois,
            "poi_positions",
            f"need one position per POI value ({domain.n_pois}), got {len(self.poi_positions)}",
        )
        for name in ("rover_positions", "rover_headings"):
            n = len(getattr(self, name))
            check(n in (0, domain.n_rovers), name,
                  f"need none or one per rover ({domain.n_rovers}), got {n}")  # fmt: skip

    def draw(self, rngs, n_rovers, poi_values):
        positions, headings = spawn_in_disc(rngs, n_rovers, self.spawn_radius)
        n_teams = len(rngs)
        if self.rover_positions:
            positions = per_team(np.array(self.rover_positions), n_teams)
        if self.rover_headings:
            headings = per_team(np.array(self.rover_headings), n_teams)
        pois = per_team(np.array(self.poi_positions), n_teams)
        return StartState(positions, headings, pois, per_team(poi_values, n_teams))

    def extent(self) -> float:
        points = [*self.poi_positions, *self.rover_positions]
        far = reach(self.obstacles(), self.boxes(), self.segments())
        return max([self.spawn_radius, *(float(np.hypot(*p)) for p in points), far])


__all__ = ["Explicit", "REDRAWS", "Ring", "RingRandom", "Scenario", "SpawnDisc", "StartState",
           "Uniform",
           "per_team", "register_scenario", "spawn_in_disc"]  # fmt: skip
