"""Rover sensing, Eqs. 15-16 of the paper.

Each rover senses an 8-vector (the order of the lab's rover-domain code):

- components 0-3: ``s_rover,q = sum_{j in J_q} 1 / delta_ij^2`` over the *other* rovers j of
  the team in quadrant q (Eq. 15);
- components 4-7: ``s_poi,q = sum_{k in K_q} V_k / delta_ik^2`` over the POIs k in quadrant
  q (Eq. 16);

with ``delta`` the bounded distance of Eq. 14 and the quadrants of
:mod:`physrover.domain.geometry` (0 behind-right, 1 front-right, 2 front-left, 3 behind-left).
"""

from __future__ import annotations

import functools

import numpy as np

from physrover.domain.geometry import Relations, relate

OBS_DIM = 8


def numerators(n_rovers: int, poi_values: np.ndarray) -> np.ndarray:
    """(E, R, N) numerator of each object's sensing term; fixed for an episode.

    1 for the other rovers (Eq. 15), 0 for the rover itself, V_k for POI k (Eq. 16).

    Args:
        n_rovers: R.
        poi_values: (E, K) POI values.
    """
    n_teams, n_pois = poi_values.shape
    out = np.empty((n_teams, n_rovers, n_rovers + n_pois))
    out[:, :, :n_rovers] = 1.0 - np.eye(n_rovers)
    out[:, :, n_rovers:] = poi_values[:, None, :]
    return out


@functools.lru_cache(maxsize=16)
def _cell_base(n_teams: int, n_rovers: int, n_objects: int) -> np.ndarray:
    """(E, R, N) index of channel 0 of each rover's observation, +4 for POI objects."""
    row = np.arange(n_teams * n_rovers).reshape(n_teams, n_rovers, 1) * OBS_DIM
    poi_offset = np.where(np.arange(n_objects) < n_rovers, 0, 4)
    base = row + poi_offset
    base.flags.writeable = False
    return base


def sense(relations: Relations, numerator: np.ndarray) -> np.ndarray:
    """Observations of all rovers of all teams (Eqs. 15-16).

    Args:
        relations: rover-to-object relations, N = R + K objects (rovers first).
        numerator: (E, R, N) from :func:`numerators`.

    Returns:
        (E, R, 8) float64 observations.
    """
    n_teams, n_rovers, n_objects = relations.delta_sq.shape
    term = numerator / relations.delta_sq
    # Scatter-add every term into its (team, rover, channel) cell with one bincount; the
    # channel is the quadrant, plus 4 for POIs.
    cell = _cell_base(n_teams, n_rovers, n_objects) + relations.quadrant
    obs = np.bincount(cell.ravel(), weights=term.ravel(), minlength=n_teams * n_rovers * OBS_DIM)
    return obs.reshape(n_teams, n_rovers, OBS_DIM)


def observe(
    rover_positions: np.ndarray,
    rover_headings: np.ndarray,
    poi_positions: np.ndarray,
    poi_values: np.ndarray,
    d_min: float,
) -> np.ndarray:
    """(E, R, 8) observations straight from positions (E, R, 2), headings (E, R), POI
    positions (E, K, 2) and values (E, K); see :func:`sense`."""
    relations = relate(rover_positions, rover_headings, poi_positions, d_min)
    return sense(relations, numerators(rover_positions.shape[1], poi_values))
