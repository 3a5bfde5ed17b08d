"""The lidar of a whole class at once, vectorised over its agents (the lanes).

:func:`~physrover.domain.sensing.lidar.lidar_agent` reads one agent at a time: for each
object (agents by index, then POIs) it finds the object's channel and adds its term there.
:func:`lidar_class` turns the loops round, as the density sensor does
(:func:`~physrover.domain.sensing.density.sense_team`): for each object, every agent of the
class (a lane) computes its distance, sector and term, and each of the object's
``n_sectors`` channels adds the term where the sector matches and +0.0 elsewhere (for
``compose = "closest"``: keeps the larger where it matches). The same terms are added to
the same channels in the same order (an object the agent does not see, or itself, adds
+0.0 everywhere, and terms are never negative, so +0.0 and a max with the starting 0 change
nothing), so the readings are :func:`lidar_agent`'s bit for bit (a test over every
composition, measure, bearing and channel layout); the masked adds are what LLVM
vectorises. The class's all-pairs agents read through here; a class that finds its
neighbours from the grid (:mod:`physrover.domain.sensing.classes`) does not.
"""

from __future__ import annotations

import math

import numpy as np

from physrover.core.compiled import jit
from physrover.domain.sensing.sectors import sector, world_sector


@jit
def lanes_scratch(n_agents, max_channels):
    """Scratch of :func:`lidar_class`: (4, R) lanes (x, y, cos, sin), (C, R) sums and
    (C, R) counts, C the widest class's channels."""
    return (np.zeros((4, n_agents)), np.zeros((max_channels, n_agents)),
            np.zeros((max_channels, n_agents), dtype=np.int64))  # fmt: skip


@jit
def lidar_class(e, first, stop, state, d_min_sq, n_sectors, radius_sq, compose, measure,
                empty, world, agent_base, poi_base, visible, poi_radius_sq, disappear,
                n_channels, scratch, obs):  # fmt: skip
    """The lidar readings of agents ``first`` to ``stop - 1`` of team ``e`` into
    ``obs[e, first:stop, :n_channels]``; the parameters are
    :func:`~physrover.domain.sensing.lidar.lidar_agent`'s (a class's row of the sensing
    table), ``scratch`` :func:`lanes_scratch`'s."""
    lanes, acc, count = scratch
    n = stop - first
    positions, cos_h, sin_h = state.rover_positions, state.cos_h, state.sin_h
    poi_positions, poi_values = state.poi_positions, state.poi_values
    px, py, cs, sn = lanes[0], lanes[1], lanes[2], lanes[3]
    for m in range(n):
        px[m] = positions[e, first + m, 0]
        py[m] = positions[e, first + m, 1]
        cs[m] = cos_h[e, first + m]
        sn[m] = sin_h[e, first + m]
    for q in range(n_channels):
        for m in range(n):
            acc[q, m] = 0.0
            count[q, m] = 0
    radius = math.sqrt(radius_sq)
    n_agents, n_pois = positions.shape[1], poi_positions.shape[1]
    for j in range(n_agents + n_pois):  # the agents by index, then the POIs
        if j < n_agents:
            xj, yj, num = positions[e, j, 0], positions[e, j, 1], 1.0
            base, reach_sq, shown = agent_base[j], radius_sq, True
        else:
            k = j - n_agents
            xj, yj, num = poi_positions[e, k, 0], poi_positions[e, k, 1], poi_values[e, k]
            base, reach_sq = poi_base, min(radius_sq, poi_radius_sq[k])
            shown = visible[k] and not (disappear[k] and state.captured[e, k])
            if not shown:
                continue
        for m in range(n):
            dx = xj - px[m]
            dy = yj - py[m]
            dist_sq = dx * dx + dy * dy
            seen = dist_sq <= reach_sq and j != first + m
            if world:
                q = world_sector(dx, dy, n_sectors)
            else:
                q = sector(cs[m] * dx + sn[m] * dy, cs[m] * dy - sn[m] * dx, n_sectors)
            if measure == 0:
                term = num / max(dist_sq, d_min_sq)  # Eq. 14
            else:
                term = num * (1.0 - math.sqrt(dist_sq) / radius)
            for s in range(n_sectors):
                hit = seen and q == s
                if compose == 2:
                    acc[base + s, m] = max(acc[base + s, m], term) if hit else acc[base + s, m]
                else:
                    acc[base + s, m] += term if hit else 0.0
                count[base + s, m] += 1 if hit else 0
    for m in range(n):
        for q in range(n_channels):
            if count[q, m] == 0:
                obs[e, first + m, q] = empty
            elif compose == 1:
                obs[e, first + m, q] = acc[q, m] / count[q, m]
            else:
                obs[e, first + m, q] = acc[q, m]


__all__ = ["lanes_scratch", "lidar_class"]
