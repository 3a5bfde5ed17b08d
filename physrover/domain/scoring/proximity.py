"""MERL's dense proximity signal: how near each rover is to the nearest POI not yet captured.

Majumdar, Khadka et al. 2020 ("Evolutionary Reinforcement Learning for Sample-Efficient
Multiagent Coordination", ICML; code ShawK91/MERL, ``rover_domain_python.py``) train their
gradient learners on a per-rover, per-step reward that carries no coupling information::

    r_i(t) = min(1, d_cap / d_i(t)),   d_i(t) = min over open POIs k of ||x_i(t) - p_k||

where a POI is open at step t if it was not captured at step t or before
(``capture_step`` -1 or later than t), ``d_cap`` is the capture radius (MERL's
``act_dist``) and a rover on a POI gets 1; with no open POI the reward is 0. Units: the
reward is dimensionless, in [0, 1]; positions in world units.

Conventions (where MERL differs, physrover's choice is stated): every POI counts whatever
its distance (MERL restricts to its sensor's range, which is 10 x the world's size, so
every POI in practice); MERL scales the reward by 10 (``reward_scaling``), physrover does
not (PPO standardises advantages, so the policy's update does not see the scale). Row 0 of
:func:`proximity_steps` is the start state, which no action produced; a rover's episode
credit sums rows 1..t.
"""

from __future__ import annotations

import numpy as np


def proximity(positions: np.ndarray, poi_positions: np.ndarray, open_pois: np.ndarray,
              d_cap: float) -> np.ndarray:  # fmt: skip
    """The proximity reward of rovers at ``positions``.

    Args:
        positions: (..., E, R, 2) rover positions, world units.
        poi_positions: (E, K, 2) POI positions.
        open_pois: (..., E, K) bool, the POIs not captured yet.
        d_cap: the capture radius, world units.

    Returns:
        (..., E, R) float64 in [0, 1].
    """
    delta = positions[..., :, None, :] - poi_positions[..., None, :, :]  # (..., E, R, K, 2)
    dist = np.sqrt((delta * delta).sum(axis=-1))
    dist = np.where(open_pois[..., None, :], dist, np.inf)
    nearest = dist.min(axis=-1, initial=np.inf)
    with np.errstate(divide="ignore"):
        return np.minimum(1.0, d_cap / nearest)  # 0 where nothing is open, 1 on a POI


def proximity_steps(world) -> np.ndarray:
    """(T + 1, E, R) the proximity reward of every recorded step of the episode ``world``
    played (rows past ``world.t`` are 0): row t from ``position_history[t]`` and the POIs
    open after step t's scoring."""
    state, t = world.state, world.t
    steps = np.arange(t + 1)[:, None, None]
    first = state.capture_step[None]  # (1, E, K)
    open_pois = (first < 0) | (first > steps)  # (t + 1, E, K)
    out = np.zeros((world.position_history.shape[0], world.n_teams, world.n_rovers))
    out[: t + 1] = proximity(world.position_history[: t + 1], state.poi_positions, open_pois,
                             world.config.d_cap)  # fmt: skip
    return out


def proximity_now(world) -> np.ndarray:
    """(E, R) the proximity reward of the world's latest step (its current positions and
    the POIs open now): row ``world.t`` of :func:`proximity_steps`, without the history."""
    state = world.state
    return proximity(state.rover_positions, state.poi_positions, ~state.captured,
                     world.config.d_cap)  # fmt: skip
