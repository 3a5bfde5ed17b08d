"""A start state given in part: ``reset(options=...)`` of the envs (:class:`StartOverrides`),
and the checks that turn a given array into the world's (E, ...) rows."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np


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


__all__ = ["StartOverrides", "team_array", "write_start"]
