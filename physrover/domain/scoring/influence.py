"""IndirectDifference: credit for the captures an agent enabled (the paper's lab's later
credit, AADILab/influence-shaping ``IndirectDifference``, ``assignment = automatic``).

An agent of a class with ``influence_radius`` rho > 0 (``[[agents]]``; the lab's UAVs, rho
5) *influences* a counted agent k (its class ``captures``) at a scored step t when they are
within rho of each other:

    phi_t(u, k) = [u != k, rho_u > 0, k counted, ||p_u(t) - p_k(t)|| <= rho_u].

``G(z \\ M)`` rescores the episode (Eqs. 11-13, with the POIs' rules) with every (t, i) of
the removal set M left out of step t's counts. Two credits, each with agent i's own whole
trajectory removed as in D (Eq. 1):

- ``"ID"`` (the lab's ``timescale = trajectory``): ``n_{k,u} = sum_t phi_t(u, k)``; k is
  *owned* by the lowest-index u with the largest ``n_{k,u}``, if it is > 0; then
  ``ID_i = G(z) - G(z \\ ({0..T} x A_i))`` with ``A_i = {i} + {k : owner(k) = i}``: an
  agent is credited with the whole trajectories of the agents it influenced most;
- ``"ID-step"`` (``timescale = timestep``, ``credit = AllOrNothing``): at each step, k is
  owned by the lowest-index u with ``phi_t(u, k)``, if any; ``ID-step_i = G(z) - G(z \\
  M_i)`` with ``M_i = ({0..T} x {i}) + {(t, k) : owner_t(k) = i}``: credited step by step.

An agent that influences nobody gets D_i exactly, so without influencers both are D.
Differences from the lab's code, on purpose: the radius is per class (the lab hard-codes
5.0); where nobody influences k at t nobody is credited (the lab credits agent 0); G is
physrover's binary capture (Eq. 11), so removing k at a step matters only where that step
decided a capture. The lab's ``manual`` assignment, ``Local``/``System``/``Difference``
credits and ``add_G`` are left out.

Cost: the influence is (T + 1, E, R, R) booleans in numpy; the rescoring one compiled pass
over (E, R, T + 1, K, R), like D++.
"""

from __future__ import annotations

import numpy as np

from physrover.core.compiled import jit
from physrover.domain.agents.classes import counted_agents, per_agent
from physrover.domain.scoring.captures import coupling_met, last_scored_step, predecessors_before
from physrover.domain.scoring.difference import team_score
from physrover.domain.scoring.rules import PoiRules

TIMESCALES = ("trajectory", "step")


def influence(world) -> np.ndarray:
    """phi (T_s, E, R, R) bool, ``[t, e, u, k]``: u influences k at scored step t (the
    module docstring) of the episode ``world`` just played; T_s scored steps."""
    config = world.config
    positions = world.position_history[: last_scored_step(config) + 1]  # (T_s, E, R, 2)
    n = world.n_rovers
    radius = per_agent(config, [c.influence_radius for c in config.agents], 0.0)
    counted = counted_agents(config)
    offset = positions[:, :, :, None, :] - positions[:, :, None, :, :]
    dist_sq = (offset * offset).sum(-1)  # (T_s, E, u, k)
    phi = dist_sq <= (radius * radius)[:, None]
    phi &= (radius > 0)[:, None] & counted[None, :] & ~np.eye(n, dtype=bool)
    return phi


def removal_sets(phi: np.ndarray, timescale: str) -> np.ndarray:
    """(E, A, T_s, R) bool: for each credited agent a, the (t, i) left out of G (module
    docstring), from the (T_s, E, R, R) influence ``phi``."""
    n_steps, n_teams, n, _ = phi.shape
    own = np.eye(n, dtype=bool)[None, :, None, :]  # a's own trajectory: (1, A, 1, R)
    if timescale == "trajectory":
        counts = phi.sum(axis=0)  # (E, u, k)
        owner = np.where(counts.max(axis=1) > 0, counts.argmax(axis=1), -1)  # (E, k)
        owned = owner[:, None, :] == np.arange(n)[None, :, None]  # (E, A, k)
        return np.broadcast_to(own | owned[:, :, None, :], (n_teams, n, n_steps, n))
    owner = np.where(phi.any(axis=2), phi.argmax(axis=2), -1)  # (T_s, E, k): lowest u
    owned = owner.transpose(1, 0, 2)[:, None] == np.arange(n)[None, :, None, None]
    return own | owned  # (E, A, T_s, R)


@jit
def replay_captures(in_range, removed, n_req, rules, out):
    """``out[e, a, k]``: POI k captured in team e's episode with the (t, i) of
    ``removed[e, a]`` (T_s, R) left out of the counts (Eq. 12 under the POIs' ``rules``, a
    :class:`~physrover.domain.scoring.rules.PoiRules`: the same :func:`coupling_met` and
    order as the episode's scoring), from the episode's record ``in_range`` (T + 1, E, R,
    K)."""
    n_teams, n_sets, n_steps, n_agents = removed.shape
    n_pois = in_range.shape[3]
    first = np.empty(n_pois, dtype=np.int64)
    near = np.empty((n_agents, n_pois), dtype=np.bool_)
    for e in range(n_teams):
        for a in range(n_sets):
            first[:] = -1
            for t in range(n_steps):
                for i in range(n_agents):
                    for k in range(n_pois):
                        near[i, k] = in_range[t, e, i, k] and not removed[e, a, t, i]
                for k in range(n_pois):
                    if first[k] >= 0 or (rules.final_only[k] and t != rules.t_final):
                        continue
                    if coupling_met(k, near, rules, n_req, -1) and predecessors_before(
                        rules.after, k, first, t
                    ):
                        first[k] = t
            for k in range(n_pois):
                out[e, a, k] = first[k] >= 0


def indirect_difference(world, timescale: str = "trajectory") -> np.ndarray:
    """(E, R) IndirectDifference of every agent for the episode ``world`` just played
    (``timescale`` "trajectory": ``ID``; "step": ``ID-step``; module docstring)."""
    if timescale not in TIMESCALES:
        raise ValueError(f"timescale must be one of {TIMESCALES}, got {timescale!r}")
    phi = influence(world)
    removed = removal_sets(phi, timescale)
    rules = world.plan.step.rules or PoiRules.build(world.config, world.n_teams, always=True)
    captured = np.empty((world.n_teams, world.n_rovers, world.n_pois), dtype=bool)
    replay_captures(world.state.in_range, removed, world.n_req, rules, captured)
    return world.G[:, None] - team_score(captured, world.state.poi_values)


__all__ = ["TIMESCALES", "indirect_difference", "influence", "removal_sets", "replay_captures"]
