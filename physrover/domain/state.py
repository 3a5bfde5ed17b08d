"""WorldState: the state of E teams as one structure of arrays, team axis first.

Every compiled kernel of the world takes this one structure (numba types a ``NamedTuple`` of
arrays natively) instead of a dozen positional arrays. Each group of arrays has one writer:

- the motion model writes the rovers (``rover_positions``, ``rover_headings`` and their
  ``cos_h``, ``sin_h``, ``rover_velocities``): the idealised step kernel, or the physical
  model from its bodies;
- the scenario writes the POIs (``poi_positions``, ``poi_values``) at reset, and the
  obstacles (``obstacles``) once;
- scoring (:func:`physrover.domain.scoring.captures.score_team`, Eqs. 11-13) writes ``poi_counts``,
  ``in_range``, ``captured``, ``captured_without``, ``capture_step`` and ``score``;
- the POIs' sight rules (:func:`physrover.domain.sensing.vanish.vanish_team`) write
  ``gone``.

The arrays are allocated once per world and updated in place; readers copy what they keep.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class WorldState(NamedTuple):
    """The state of E teams of R rovers and K POIs (see the module docstring)."""

    rover_positions: np.ndarray
    """(E, R, 2) float64, world units."""
    rover_headings: np.ndarray
    """(E, R) float64, radians in [-pi, pi]."""
    cos_h: np.ndarray
    """(E, R) float64: cos of the headings (see :mod:`physrover.domain.motion.ideal`)."""
    sin_h: np.ndarray
    """(E, R) float64: sin of the headings."""
    rover_velocities: np.ndarray
    """(E, R, 2) float64, world units per step: the physical bodies' velocity at the end of
    the last step (zero after reset). Zero under the idealised kinematics, which has no
    velocity (its last move is ``position_history[t] - position_history[t - 1]``; writing it
    here cost 5% of the fused step)."""
    poi_positions: np.ndarray
    """(E, K, 2) float64, world units."""
    poi_values: np.ndarray
    """(E, K) float64, positive."""
    obstacles: np.ndarray
    """(E, M, 5) float64: the scenario's static obstacles as capsules ``[ax, ay, bx, by,
    radius]`` (a disc has A = B; a box is its four edges), world units
    (:mod:`physrover.domain.obstacles`)."""
    poi_counts: np.ndarray
    """(E, K) int64: rovers within d_cap of each POI at the latest scored step (Eq. 13)."""
    in_range: np.ndarray
    """(T + 1, E, R, K) bool: rover i within d_cap of POI k at step t (Eq. 13), the record
    of every scored step of the episode (rows of unscored steps stay False); what
    counterfactual credits (D++) replay."""
    captured: np.ndarray
    """(E, K) bool: captured at some step so far (Eq. 12)."""
    captured_without: np.ndarray
    """(E, R, K) bool: the same with rover i removed (the counterfactual of D, Eq. 1)."""
    capture_step: np.ndarray
    """(E, K) int64: the first step at which each POI was captured, -1 if none yet."""
    score: np.ndarray
    """(E,) float64: G so far (Eq. 11)."""
    gone: np.ndarray
    """(E, K) bool: out of every agent's sight from now on (``[[pois]] disappear``)."""

    @classmethod
    def zeros(
        cls, n_teams: int, n_rovers: int, n_pois: int, steps: int = 0, n_obstacles: int = 0
    ) -> WorldState:
        """A state of the given sizes (``steps`` per episode), every array allocated
        (C-contiguous) and zeroed, the scoring ones as at the start of an episode
        (:func:`physrover.domain.state.start_episode`: no capture yet)."""
        e, r, k = n_teams, n_rovers, n_pois
        state = cls(
            rover_positions=np.zeros((e, r, 2)),
            rover_headings=np.zeros((e, r)),
            cos_h=np.zeros((e, r)),
            sin_h=np.zeros((e, r)),
            rover_velocities=np.zeros((e, r, 2)),
            poi_positions=np.zeros((e, k, 2)),
            poi_values=np.zeros((e, k)),
            obstacles=np.zeros((e, n_obstacles, 5)),
            poi_counts=np.zeros((e, k), dtype=np.int64),
            in_range=np.zeros((steps + 1, e, r, k), dtype=bool),
            captured=np.zeros((e, k), dtype=bool),
            captured_without=np.zeros((e, r, k), dtype=bool),
            capture_step=np.zeros((e, k), dtype=np.int64),
            score=np.zeros(e),
            gone=np.zeros((e, k), dtype=bool),
        )
        start_episode(state)
        return state


def start_episode(state: WorldState, teams: np.ndarray | None = None) -> None:
    """Forget every capture in ``state``: the start of an episode, before step 0 is scored;
    of the ``teams`` (an (E,) bool mask) only, if given."""
    if teams is None:
        teams = slice(None)
    state.poi_counts[teams] = 0
    state.in_range[:, teams] = False
    state.captured[teams] = False
    state.captured_without[teams] = False
    state.capture_step[teams] = -1
    state.score[teams] = 0.0
    state.gone[teams] = False


__all__ = ["WorldState", "start_episode"]
