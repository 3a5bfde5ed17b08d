"""The classes' lidar of a whole team at once, vectorised over the observing agents.

When every compiled class of a team reads as the density sensor does (four sectors of
heading, a sum of inverse squares, :mod:`physrover.domain.sensing.lidar`) in one channel
layout, the classes differ only in their radius, the POIs they see (``visible_to``,
``sense_radius``) and their ``empty`` value. Those become per-observer *lanes*
(:class:`Lanes`), and :func:`sense_lanes` reads every agent of the team in one loop per
object, the density sensor's scheme (:func:`physrover.domain.sensing.density.sense_team`):
each object adds its term, or +0.0, to every observer's four sums of its block. A channel
that saw something has a sum > 0 (every term is: an agent's is ``1 / max(d^2, d_min^2)``, a
POI's ``V_k / max(d^2, d_min^2)`` with ``V_k > 0``, which every reset checks), so a sum of
0 reads ``empty``. (A term would round to 0 only for a distance above 1e154, or a POI
value below about 1e-300 times the squared distance.)

The sums are the scalar kernel's (:func:`~physrover.domain.sensing.lidar.lidar_agent`) bit
for bit: the same terms in the same order (agents by index, then POIs), and an unseen
object adds +0.0 to a sum that starts at +0.0 and only grows. No branch depends on the
layout, which in a run changes every step (a branch per pair that the predictor cannot
learn cost the scalar kernel most of its time).

Speed (2026-12-05, one core of a 2-core AMD EPYC Zen 4, ``benchmarks/configs/mixed15.toml``,
50 teams): see ``docs/performance.md``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from physrover.core.compiled import jit
from physrover.domain.sensing.sectors import quadrant

PAD = 16
"""The loops over observers run over a multiple of this many lanes (as the density
sensor's: LLVM vectorises them 4 doubles x 4 interleaved)."""


class Lanes(NamedTuple):
    """Each observing agent's sensing choices, for :func:`sense_lanes` (module docstring).
    ``on`` False: the team's classes differ in more than these (the arrays are then
    empty and unused)."""

    on: bool
    """Whether the team is sensed by :func:`sense_lanes`."""
    radius_sq: np.ndarray
    """(W,) float64: observer i sees the agents within this squared distance (padded
    lanes: -1, nothing)."""
    poi_radius_sq: np.ndarray
    """(K, W) float64: observer i sees POI k within this squared distance (-1: never, a
    POI its class does not see)."""
    empty: np.ndarray
    """(R,) float64: the reading of a channel of agent i with nothing in it."""
    sensed: np.ndarray
    """(R,) bool: the agents whose readings are written (a class with a Python sensor is
    left to it)."""
    block: np.ndarray
    """(R,) int64: the first channel of agent j's terms, the same for every observer."""
    runs: np.ndarray
    """(n + 1,) int64: the agents in runs of one block, run m from ``runs[m]`` to
    ``runs[m + 1]`` (a class is a run, or several classes that share channels)."""
    poi_base: int
    """The first channel of the POIs' terms."""
    n_channels: int
    """Channels of every observer."""


def no_lanes() -> Lanes:
    """The :class:`Lanes` of a team that is sensed agent by agent."""
    empty_f, empty_i = np.zeros(0), np.zeros(0, np.int64)
    return Lanes(False, empty_f, np.zeros((0, 0)), empty_f, np.zeros(0, bool), empty_i,
                 np.zeros(1, np.int64), 0, 0)  # fmt: skip


def build_lanes(rows: list[tuple], n_pois: int) -> Lanes:
    """The lanes of a team from its classes' rows, one ``(first, stop, radius_sq,
    agent_base, poi_base, visible, poi_radius_sq, empty, n_channels, compiled)`` per class
    (as :class:`~physrover.domain.sensing.classes.ClassSensing` holds them); every compiled
    row must read as the density sensor in one layout, which the caller has checked."""
    n_agents = max(row[1] for row in rows)
    width = -(-n_agents // PAD) * PAD
    radius_sq = np.full(width, -1.0)
    poi_radius_sq = np.full((n_pois, width), -1.0)
    empty = np.zeros(n_agents)
    sensed = np.zeros(n_agents, bool)
    block, poi_base, n_channels = np.zeros(n_agents, np.int64), 0, 0
    for first, stop, r_sq, agent_base, base, visible, poi_r_sq, value, size, compiled in rows:
        if not compiled:
            continue
        radius_sq[first:stop] = r_sq
        for k in range(n_pois):
            poi_radius_sq[k, first:stop] = min(r_sq, poi_r_sq[k]) if visible[k] else -1.0
        empty[first:stop] = value
        sensed[first:stop] = True
        block, poi_base, n_channels = np.asarray(agent_base, np.int64), int(base), int(size)
    starts = [j for j in range(n_agents) if j == 0 or block[j] != block[j - 1]]
    runs = np.array([*starts, n_agents], np.int64)
    return Lanes(True, radius_sq, poi_radius_sq, empty, sensed, block, runs, poi_base,
                 n_channels)  # fmt: skip


@jit
def lanes_scratch(lanes, n_agents):
    """Scratch of :func:`sense_lanes`: (4 + n_channels, W) float64, rows the observers'
    x, y, cos and sin (padded lanes: at the origin facing +x, never read back), then each
    channel's sums."""
    width = max(-(-n_agents // PAD) * PAD, 1)
    scratch = np.zeros((4 + lanes.n_channels, width))
    scratch[2, :] = 1.0
    return scratch


@jit
def sense_lanes(e, state, lanes, d_min_sq, scratch, obs):
    """Every agent of team ``e`` through the lidar its :class:`Lanes` describe, into
    ``obs[e]`` (R, >= n_channels) float32, the columns past ``n_channels`` set to 0 (rows
    of agents not ``sensed`` are left as they were); ``d_min_sq`` the bound of Eq. 14
    squared, ``scratch`` from :func:`lanes_scratch`. Per channel: the sum of the terms of
    Eq. 14 (numerator 1 for an agent, V_k for POI k) of what the observer sees in it, or
    its ``empty`` value if it sees nothing there."""
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    poi_positions, poi_values = state.poi_positions, state.poi_values
    n_agents, n_channels, width = cos_h.shape[1], lanes.n_channels, scratch.shape[1]
    px, py, cs, sn = scratch[0], scratch[1], scratch[2], scratch[3]
    reach, poi_reach = lanes.radius_sq, lanes.poi_radius_sq
    for i in range(n_agents):
        px[i] = positions[e, i, 0]
        py[i] = positions[e, i, 1]
        cs[i] = cos_h[e, i]
        sn[i] = sin_h[e, i]
    for q in range(4, 4 + n_channels):
        for i in range(width):
            scratch[q, i] = 0.0
    # The two loops differ only in the numerator, who is seen and the block; as in the
    # density sensor, they stay written out so that LLVM vectorises both (a count of what
    # each channel saw, four more sums, stopped it: 6.0 ms instead of 2.6 for 50 teams
    # sensed 50 times). The agents go by runs of one block, its four rows chosen once a
    # run: chosen for every agent, the agents' loop took 2.5 ms of the 3.6 that 60 mixed
    # teams' sensing over an episode's 51 layouts costs, 1.5 by runs (2026-12-06).
    for m in range(lanes.runs.shape[0] - 1):  # the agents by index, numerator 1
        q0 = 4 + lanes.block[lanes.runs[m]]
        a0, a1, a2, a3 = scratch[q0], scratch[q0 + 1], scratch[q0 + 2], scratch[q0 + 3]
        for j in range(lanes.runs[m], lanes.runs[m + 1]):
            xj, yj = positions[e, j, 0], positions[e, j, 1]
            for i in range(width):
                dx = xj - px[i]
                dy = yj - py[i]
                dist_sq = dx * dx + dy * dy
                seen = (dist_sq <= reach[i]) & (i != j)
                w = 1.0 / max(dist_sq, d_min_sq) if seen else 0.0  # Eq. 14
                q = quadrant(cs[i] * dx + sn[i] * dy, cs[i] * dy - sn[i] * dx)
                a0[i] += w if q == 0 else 0.0
                a1[i] += w if q == 1 else 0.0
                a2[i] += w if q == 2 else 0.0
                a3[i] += w if q == 3 else 0.0
    q0 = 4 + lanes.poi_base
    a0, a1, a2, a3 = scratch[q0], scratch[q0 + 1], scratch[q0 + 2], scratch[q0 + 3]
    for k in range(poi_positions.shape[1]):  # then the POIs in sight, numerator V_k
        if state.gone[e, k]:
            continue
        xk, yk, value, reach_k = poi_positions[e, k, 0], poi_positions[e, k, 1], \
            poi_values[e, k], poi_reach[k]  # fmt: skip
        for i in range(width):
            dx = xk - px[i]
            dy = yk - py[i]
            dist_sq = dx * dx + dy * dy
            seen = dist_sq <= reach_k[i]
            w = value / max(dist_sq, d_min_sq) if seen else 0.0
            q = quadrant(cs[i] * dx + sn[i] * dy, cs[i] * dy - sn[i] * dx)
            a0[i] += w if q == 0 else 0.0
            a1[i] += w if q == 1 else 0.0
            a2[i] += w if q == 2 else 0.0
            a3[i] += w if q == 3 else 0.0
    for i in range(n_agents):
        if not lanes.sensed[i]:
            continue
        # ``empty`` read before the loop makes the choice below a select, not a branch on
        # what the agent saw, which the predictor cannot learn: 4.5 -> 3.0 ms for 60 mixed
        # teams sensed over an episode's 51 layouts (docs/performance.md)
        empty = lanes.empty[i]
        for q in range(n_channels):  # a sum of 0: nothing seen (module docstring)
            total = scratch[4 + q, i]
            obs[e, i, q] = total if total > 0.0 else empty
        for q in range(n_channels, obs.shape[2]):
            obs[e, i, q] = 0.0


__all__ = ["PAD", "Lanes", "build_lanes", "lanes_scratch", "no_lanes", "sense_lanes"]
