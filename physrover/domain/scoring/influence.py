"""IndirectDifference: credit for the captures an agent enabled (the paper's lab's later
credit, AADILab/influence-shaping ``IndirectDifference``, ``assignment = automatic``;
``submodules/rovers/.../rewards/computer.hpp``, ``RewardComputer::compute``).

An agent of a class with ``influence_radius`` rho > 0 (``[[agents]]``; the lab's UAVs, rho
5) *influences* a counted agent k (its class ``captures``) at a scored step t when they are
within rho of each other:

    phi_t(u, k) = [u != k, rho_u > 0, k counted, ||p_u(t) - p_k(t)|| <= rho_u].

``G(z \\ M)`` rescores the episode (Eqs. 11-13, with the POIs' rules, a distance-valued
POI at its best value over the agents left in) with every (t, i) of the removal set M left
out of step t. Each credit removes agent i's own whole trajectory as D does (Eq. 1), and
with it:

- ``"ID"`` (the lab's ``timescale = trajectory``): ``n_{k,u} = sum_t phi_t(u, k)``; k is
  *owned* by the lowest-index u with the largest ``n_{k,u}``, if it is > 0; then
  ``ID_i = G(z) - G(z \\ ({0..T} x A_i))`` with ``A_i = {i} + {k : owner(k) = i}``: an
  agent is credited with the whole trajectories of the agents it influenced most;
- ``"ID-step"`` (``timescale = timestep``, ``credit = AllOrNothing``): at each step, k is
  owned by the lowest-index u with ``phi_t(u, k)``, if any; ``ID-step_i = G(z) - G(z \\
  M_i)`` with ``M_i = ({0..T} x {i}) + {(t, k) : owner_t(k) = i}``: credited step by step;
- ``"ID-step-local"`` (``credit = Local``): ``M_i`` takes every (t, k) with
  ``phi_t(i, k)``, shared by every agent near k at t;
- ``"ID-step-system"`` (``credit = System``): every (t, k) with ``phi_t(u, k)`` for any u,
  the same for every agent, so an agent that influences nobody is credited too;
- ``"ID-step-difference"`` (``credit = Difference``): the (t, k) that i alone influences
  (``phi_t(i, k)`` and no other u's);
- ``"ID-step-all-or-nothing-lab"``: AllOrNothing as the lab's code computes it, where
  nobody influences k at t agent 0 owns it (``create_allornothing_influence_array``:
  ``highest_influence = -1``, so the first agent takes a (t, k) of influence 0); a
  compatibility option to get the lab's numbers back (below).

An agent that influences nobody gets D_i exactly (but under ``"ID-step-system"``), so
without influencers all are D. Differences from the lab's code, on purpose:

- the radius is per class (the lab hard-codes 5.0), and any class may influence (the lab's
  ``type() == "uav"``) any counted class (``"rover"``);
- under AllOrNothing, where nobody influences k at t nobody is credited (the lab's
  ``highest_influence = -1`` credits agent 0).

A (t, k) removed at a step is left out of step t; the lab moves the agent to (-1, -1),
which its constraints read as an infinite distance (``custom_env.py``,
``_step_is_satisfied``): the same.

The lab's ``manual`` assignment is ``"ID-manual"`` (:func:`manual_difference`), its
``add_G`` a class's ``feedback_plus_G`` (:class:`~physrover.domain.scoring.credit.ByClass`).

Cost: the influence is (T + 1, E, R, R) booleans in numpy; the rescoring one compiled pass
over (E, R, T + 1, K, R), like D++.
"""

from __future__ import annotations

import numpy as np

from physrover.core.compiled import jit
from physrover.domain.agents.classes import counted_agents, per_agent
from physrover.domain.agents.failures import alive_through
from physrover.domain.scoring.captures import (
    coupling_met,
    last_scored_step,
    nearest_value,
    predecessors_before,
)
from physrover.domain.scoring.difference import team_score
from physrover.domain.scoring.rules import PoiRules

TIMESCALES = ("trajectory", "step")

STEP_RULES = ("all-or-nothing", "local", "system", "difference", "all-or-nothing-lab")
"""Who is credited with a (t, k) at the ``"step"`` timescale (the lab's ``credit``:
AllOrNothing, Local, System, Difference; and AllOrNothing with the lab's agent 0 rule;
module docstring)."""


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
    live = alive_history(world, len(positions))
    if live is not None:  # a failed agent influences nobody and is influenced by nobody
        phi &= live[:, :, :, None] & live[:, :, None, :]
    return phi


def alive_history(world, n_steps: int) -> np.ndarray | None:
    """(n_steps, E, R) bool: which agents were alive at each of the episode's first
    ``n_steps`` states (:mod:`physrover.domain.agents.failures`); None if none can fail."""
    failures = world.plan.step.failures
    return None if failures is None else alive_through(failures.at, n_steps)


def removal_sets(phi: np.ndarray, timescale: str, rule: str = "all-or-nothing") -> np.ndarray:
    """(E, A, T_s, R) bool: for each credited agent a, the (t, i) left out of G (module
    docstring), from the (T_s, E, R, R) influence ``phi``; ``rule`` (:data:`STEP_RULES`)
    says who owns a (t, k) at the ``"step"`` timescale."""
    n_steps, n_teams, n, _ = phi.shape
    own = np.eye(n, dtype=bool)[None, :, None, :]  # a's own trajectory: (1, A, 1, R)
    if timescale == "trajectory":
        counts = phi.sum(axis=0)  # (E, u, k)
        owner = np.where(counts.max(axis=1) > 0, counts.argmax(axis=1), -1)  # (E, k)
        owned = owner[:, None, :] == np.arange(n)[None, :, None]  # (E, A, k)
        return np.broadcast_to(own | owned[:, :, None, :], (n_teams, n, n_steps, n))
    by_agent = phi.transpose(1, 2, 0, 3)  # (E, u, T_s, k): what u influences at t
    if rule == "local":
        owned = by_agent
    elif rule == "system":
        owned = np.broadcast_to(by_agent.any(axis=1, keepdims=True), by_agent.shape)
    elif rule == "difference":
        alone = by_agent.sum(axis=1, keepdims=True) == 1
        owned = by_agent & alone
    else:  # all-or-nothing: the lowest-index influencer (the lab's: agent 0 if none)
        owner = phi.argmax(axis=2)  # (T_s, E, k)
        if rule == "all-or-nothing":
            owner = np.where(phi.any(axis=2), owner, -1)
        owned = owner.transpose(1, 0, 2)[:, None] == np.arange(n)[None, :, None, None]
    return own | owned  # (E, A, T_s, R)


@jit
def replay_captures(in_range, removed, n_req, rules, out, positions=None, poi_positions=None):
    """``out[e, a, k]``: what POI k is worth (times its value V_k) in team e's episode with
    the (t, i) of ``removed[e, a]`` (T_s, R) left out of step t: 1.0 if it is captured, else
    0.0 (Eq. 12 under the POIs' ``rules``, a :class:`~physrover.domain.scoring.rules.PoiRules`:
    the same :func:`coupling_met` and order as the episode's scoring), or for a POI valued by
    distance its best (or final) value over the agents left in
    (:func:`~physrover.domain.scoring.captures.nearest_value`), from the episode's record
    ``in_range`` (T + 1, E, R, K) and, for valued POIs only, the agents' ``positions``
    (T + 1, E, R, 2) and ``poi_positions`` (E, K, 2), world units. ``out`` (E, A, K) may be
    bool, where no POI is valued by distance."""
    n_teams, n_sets, n_steps, n_agents = removed.shape
    n_pois = in_range.shape[3]
    first = np.empty(n_pois, dtype=np.int64)
    best = np.empty(n_pois)
    near = np.empty((n_agents, n_pois), dtype=np.bool_)
    left_in = np.empty(n_agents, dtype=np.bool_)
    for e in range(n_teams):
        for a in range(n_sets):
            first[:] = -1
            best[:] = 0.0
            for t in range(n_steps):
                for i in range(n_agents):
                    for k in range(n_pois):
                        near[i, k] = in_range[t, e, i, k] and not removed[e, a, t, i]
                for k in range(n_pois):
                    if rules.final_only[k] and t != rules.t_final:
                        continue
                    if rules.valued[k]:
                        if positions is None:  # compiled away where none is given
                            continue
                        if coupling_met(
                            k, near, rules.typed, rules.require, rules.agent_class, n_req, -1
                        ):
                            for i in range(n_agents):
                                left_in[i] = rules.counts_for[k, i] and not removed[e, a, t, i]
                            value = nearest_value(positions[t, e], poi_positions[e, k, 0],
                                                  poi_positions[e, k, 1], left_in, n_req[k],
                                                  -1)  # fmt: skip
                            best[k] = max(best[k], value)
                            if value > 0.0 and first[k] < 0:
                                first[k] = t
                        continue
                    if first[k] >= 0:
                        continue
                    if coupling_met(
                        k, near, rules.typed, rules.require, rules.agent_class, n_req, -1
                    ) and predecessors_before(rules.after, k, first, t):
                        first[k] = t
            for k in range(n_pois):
                out[e, a, k] = best[k] if rules.valued[k] else first[k] >= 0


def indirect_difference(world, timescale: str = "trajectory",
                        rule: str = "all-or-nothing") -> np.ndarray:  # fmt: skip
    """(E, R) IndirectDifference of every agent for the episode ``world`` just played
    (``timescale`` "trajectory": ``ID``; "step": ``ID-step`` under ``rule``, one of
    :data:`STEP_RULES`; module docstring)."""
    if timescale not in TIMESCALES:
        raise ValueError(f"timescale must be one of {TIMESCALES}, got {timescale!r}")
    if rule not in STEP_RULES:
        raise ValueError(f"rule must be one of {STEP_RULES}, got {rule!r}")
    phi = influence(world)
    return world.G[:, None] - rescore(world, removal_sets(phi, timescale, rule))


def manual_difference(world) -> np.ndarray:
    """(E, R) the lab's IndirectDifference with ``assignment = manual``: ``G(z) - G(z \\
    ({0..T} x L_i))``, ``L_i`` the agents listed in agent i's class's ``manual_removal``
    (itself only if listed; an agent whose class lists nobody gets 0), for the episode
    ``world`` just played (``RewardComputer::compute``, ``compute_without_inds``)."""
    config = world.config
    listed = np.zeros((world.n_rovers, world.n_rovers), dtype=bool)  # [a, i]
    start = 0
    for c in config.agents:
        listed[start : start + c.count, list(c.manual_removal)] = True
        start += c.count
    n_steps = last_scored_step(config) + 1
    removed = np.broadcast_to(listed[None, :, None, :],
                              (world.n_teams, world.n_rovers, n_steps, world.n_rovers))  # fmt: skip
    return world.G[:, None] - rescore(world, np.ascontiguousarray(removed))


def rescore(world, removed: np.ndarray) -> np.ndarray:
    """(E, A) ``G(z \\ M)`` of the episode ``world`` just played for each removal set
    ``removed`` (E, A, T_s, R) bool (:func:`replay_captures`, then Eq. 11)."""
    rules = world.plan.step.rules or PoiRules.build(world.config, world.n_teams, always=True)
    live = alive_history(world, removed.shape[2])
    if live is not None:  # a failed agent is out of every replay, as of the episode
        removed = np.ascontiguousarray(removed | ~live.transpose(1, 0, 2)[:, None])
    worth = np.empty((world.n_teams, removed.shape[1], world.n_pois))
    replay_captures(world.state.in_range, removed, world.n_req, rules, worth,
                    world.position_history, world.poi_positions)  # fmt: skip
    return team_score(worth, world.state.poi_values)


__all__ = [
    "STEP_RULES",
    "TIMESCALES",
    "indirect_difference",
    "influence",
    "manual_difference",
    "removal_sets",
    "rescore",
    "replay_captures",
]
