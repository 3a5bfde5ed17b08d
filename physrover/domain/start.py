"""The start of a reset: the scenario's draws under its redraw mode (:class:`StartDraws`),
with the classes' spawns and the failing agents drawn after them; a start state given in
part, ``reset(options=...)`` of the envs (:class:`StartOverrides`); and the checks that
turn a given array into the world's (E, ...) rows."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from physrover.domain.agents.classes import spawn, spawn_pois
from physrover.domain.agents.failures import draw_failures
from physrover.domain.scenarios import StartState


class StartDraws:
    """A world's start states: the scenario's draw (team e's from ``rngs[e]`` alone) and
    the classes' and the POIs' spawn rules, then shared as the scenario's ``redraw`` mode says
    (:mod:`physrover.domain.scenarios`); and the failing agents' steps, shared the same way.
    ``fresh_teams``: under ``redraw = "generation"``, the last this many teams draw their
    own (the CCEA's evaluation episodes), the others share team 0's, or with ``groups`` = n
    the draws of teams 0 to n - 1 in turn (team e takes team e % n's: the CCEA's
    ``rollouts``, each team's n episodes on n starts every team shares)."""

    def __init__(self, config, n_teams: int):
        self.config, self.n_teams = config, int(n_teams)
        self._fixed: StartState | None = None  # redraw = "never"

    def shared(self, fresh_teams: int) -> int:
        """Under redraw = "generation": how many teams share team 0's start."""
        return self.n_teams - min(fresh_teams, self.n_teams - 1)

    def draw(self, rngs, fresh_teams: int, groups: int = 1) -> StartState:
        """The start states of this reset of the teams whose generators ``rngs`` are."""
        config, n_rovers = self.config, self.config.n_rovers
        scenario, values = config.scenario, np.asarray(config.poi_values, dtype=float)
        start = scenario.draw(rngs, n_rovers, values)
        if not isinstance(start, StartState):
            raise TypeError(f"{type(scenario).__name__}.draw must return a StartState")
        start = self._spawned(start, rngs)
        if scenario.redraw == "episode":
            return start
        if scenario.redraw == "never":
            if self._fixed is None:
                rng = np.random.default_rng(scenario.layout_seed)
                fixed = self._spawned(scenario.draw([rng], n_rovers, values), [rng])
                self._fixed = StartState(*(a[0] for a in fixed))
            out = [np.array(a, dtype=np.float64) for a in start]
            for arr, row in zip(out, self._fixed, strict=True):
                arr[:] = row
            return StartState(*out)
        # "generation": team e % groups's draw for every team but the fresh ones
        shared = self.shared(fresh_teams)
        out = [np.array(a, dtype=np.float64) for a in start]
        for arr in out:
            arr[:shared] = arr[np.arange(shared) % groups]
        return StartState(*out)

    def _spawned(self, start: StartState, rngs) -> StartState:
        """``start`` with the classes' spawn rules and then the POIs' applied, drawn after
        the scenario's (:func:`~physrover.domain.agents.classes.spawn`, ``spawn_pois``)."""
        config = self.config
        if config.agents:
            start = start._replace(rover_positions=np.array(start.rover_positions, float))
            spawn(start.rover_positions, config, rngs)
        if any(poi.spawn != "scenario" for poi in config.pois):
            start = start._replace(poi_positions=np.array(start.poi_positions, float))
            spawn_pois(start.poi_positions, config, rngs)
        return start

    def failures(self, rngs, fresh_teams: int, groups: int = 1) -> np.ndarray:
        """(len(rngs), R) int64: the failure steps of this reset
        (:func:`~physrover.domain.agents.failures.draw_failures`), drawn after the start;
        under redraw = "generation" the teams that share a start share them too."""
        at = draw_failures(self.config, rngs)
        if self.config.scenario.redraw == "generation" and len(rngs) == self.n_teams:
            shared = self.shared(fresh_teams)
            at[:shared] = at[np.arange(shared) % groups]
        return at


@dataclass(frozen=True)
class StartOverrides:
    """Parts of a start state given explicitly (``reset(options=...)``); any field left
    ``None`` is drawn by the scenario as usual.

    Each array is given either for one team (shapes below) or with a leading team axis E.

    Attributes:
        rover_positions: (R, 2) world positions.
        rover_headings: (R,) radians.
        poi_positions: (K, 2) world positions.
        poi_values: (K,) POI values (positive).
    """

    rover_positions: Any = None
    rover_headings: Any = None
    poi_positions: Any = None
    poi_values: Any = None

    @classmethod
    def from_options(cls, options: Mapping[str, Any] | None) -> StartOverrides | None:
        """Build from a gymnasium ``reset(options=...)`` dict; unknown keys are errors."""
        if not options:
            return None
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ValueError(
                f"unknown reset option {unknown[0]!r}; known options: {', '.join(sorted(known))}"
            )
        return cls(**options)


def team_array(name: str, value: Any, shape: tuple[int, ...], n_teams: int) -> np.ndarray:
    """``value`` as a float64 array of shape (E, *shape), broadcast from ``shape`` if needed."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape == shape:
        arr = np.broadcast_to(arr, (n_teams, *shape))
    elif arr.shape != (n_teams, *shape):
        raise ValueError(f"{name} must have shape {shape} or {(n_teams, *shape)}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def write_start(state, rows, start, overrides: StartOverrides | None, n_teams: int) -> None:
    """Write a reset's start into the world's ``state`` rows ``rows`` (every team, or some
    teams' indices): ``start`` the scenario's :class:`~physrover.domain.scenarios.StartState`
    drawn for those teams, replaced where ``overrides`` give a part (for one team, or for
    all ``n_teams``, of which the rows' are taken)."""
    o = overrides or StartOverrides()
    n, r, k = len(state.score[rows]), state.cos_h.shape[1], state.poi_values.shape[1]
    for name, shape in (("rover_positions", (r, 2)), ("rover_headings", (r,)),
                        ("poi_positions", (k, 2)), ("poi_values", (k,))):  # fmt: skip
        value = getattr(o, name)
        if value is None:
            getattr(state, name)[rows] = team_array(name, getattr(start, name), shape, n)
        else:
            getattr(state, name)[rows] = team_array(name, value, shape, n_teams)[rows]
    if np.any(state.poi_values[rows] <= 0):
        raise ValueError("poi_values must be positive")


__all__ = ["StartDraws", "StartOverrides", "team_array", "write_start"]
