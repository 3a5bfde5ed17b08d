"""Captures and the team score, compiled: Eqs. 11-13 and the counterfactual captures of D
(Eq. 1), for the paper's POIs and under POI rules (:mod:`physrover.domain.scoring.rules`).

- Eq. 13: agent i is in range of POI k at step t when ``||p_i - p_k||^2 <= d_cap^2``
  (the bounded distance of Eq. 14, ``max(d, d_min) <= d_cap``, is the same since the config
  keeps ``d_min <= d_cap`` and every capture radius ``>= d_min``);
- Eq. 12: POI k is captured at step t when at least ``n_req`` agents are in range of it;
- Eq. 11: ``G = sum_k V_k max_t I_kt``: each POI counts once, whenever it was captured;
- Eq. 1's null counterfactual: the same captures without agent i (``captured_without``),
  tracked online, so D costs O(E R K) a step.

Which steps are scored is :func:`last_scored_step`'s rule: after reset and after every step
(``steps + 1`` states), or all but the last (``scored_states = "before-steps"``).

:func:`score_team` writes ``state``'s scoring arrays for one team; the compiled step
(:mod:`physrover.domain.step`) calls it after sensing, and the tests compare it with plain
loops (``tests/oracles.py``).
"""

from __future__ import annotations

import numpy as np

from physrover.core.compiled import jit, jit_inline
from physrover.domain.agents.failures import alive


def last_scored_step(config) -> int:
    """The last step whose state counts for captures (``[domain] scored_states``): ``steps``
    (every state after reset and after each step), or ``steps - 1`` ("before-steps")."""
    return config.steps if config.scored_states == "all" else config.steps - 1


@jit
def score_team(e, state, d_cap_sq, n_req, t, rules=None, counted=None, failures=None):
    """Score step ``t`` of team ``e`` (Eqs. 11-13 and D's counterfactual captures) in
    ``state``'s scoring arrays; ``n_req`` (K,) int64 is each POI's coupling; ``rules`` a
    :class:`~physrover.domain.scoring.rules.PoiRules` or None (the paper's POIs: the rules'
    branches are compiled away). Without rules, ``counted`` (R,) bool, if given, are the
    agents that count toward couplings (the others are never in range: a class that does
    not capture); with rules, their ``counts_for`` says it. ``failures``
    (:class:`~physrover.domain.agents.failures.Failures`, None compiles it away): an agent
    not alive at t is in range of nothing (and out of a distance value's nearest)."""
    positions, poi_positions = state.rover_positions, state.poi_positions
    n_rovers = positions.shape[1]
    n_pois = poi_positions.shape[1]
    count = state.poi_counts[e]
    near = state.in_range[t, e]
    captured, captured_without = state.captured, state.captured_without
    for k in range(n_pois):
        px = poi_positions[e, k, 0]
        py = poi_positions[e, k, 1]
        n = 0
        for i in range(n_rovers):
            dx = px - positions[e, i, 0]
            dy = py - positions[e, i, 1]
            radius_sq = d_cap_sq if rules is None else rules.capture_radius_sq[k, i]
            inside = dx * dx + dy * dy <= radius_sq  # Eq. 13
            if rules is not None:
                inside = inside and rules.counts_for[k, i]
            elif counted is not None:
                inside = inside and counted[i]
            inside = inside and alive(failures, e, t, i)
            near[i, k] = inside
            n += np.int64(inside)
        count[k] = n
    total = 0.0
    for k in range(n_pois):
        if rules is not None:
            if rules.final_only[k] and t != rules.t_final:
                pass
            elif rules.valued[k]:
                score_by_distance(e, k, near, state, rules, n_req, t, failures)
            else:
                capture_by_rules(e, k, near, count, t, rules.typed, rules.require,
                                 rules.agent_class, rules.after, rules.step_without, n_req,
                                 captured, state.capture_step, captured_without)  # fmt: skip
        else:
            if count[k] >= n_req[k]:  # Eq. 12
                if not captured[e, k]:
                    state.capture_step[e, k] = t
                    captured[e, k] = True
            for i in range(n_rovers):  # Eq. 12 without rover i
                if count[k] - np.int64(near[i, k]) >= n_req[k]:
                    captured_without[e, i, k] = True
        if rules is not None and rules.valued[k]:  # the lab's distance value
            total += state.poi_values[e, k] * rules.value_best[e, k]
        elif captured[e, k]:  # Eq. 11
            total += state.poi_values[e, k]
    state.score[e] = total


@jit_inline
def predecessors_before(after, k, first_steps, t):
    """Whether every POI j with ``after[k, j]`` was first captured (``first_steps[j]``, -1:
    never) at a step before ``t``."""
    for j in range(after.shape[1]):
        if after[k, j] and (first_steps[j] < 0 or first_steps[j] >= t):
            return False
    return True


@jit_inline
def capture_by_rules(e, k, near, count, t, typed, require, agent_class, after, step_without,
                     n_req, captured, capture_step, captured_without):  # fmt: skip
    """Eq. 12 for POI k of team e at step t under POI rules (:mod:`physrover.domain.scoring.rules`;
    its ``final_only`` checked and not valued by distance), for the team and for each
    counterfactual without rover i; the counts are this step's. The rules' arrays come one
    by one (``typed`` to ``step_without``, :class:`~physrover.domain.scoring.rules.PoiRules`'
    fields), the state's too: as a helper inlined once per POI and step that took the rules'
    and the state's tuples it cost more than its own work (2026-12-06,
    ``benchmarks/configs/chain.toml``'s 60 teams scored over an episode's 51 layouts: 2.5
    ms with the tuples, 1.7 without; the paper's POIs: 0.5). Measured, not a rule: the same
    change to :func:`~physrover.domain.agents.roles.class_command` made the move slower.

    Leaving an agent out never raises a count, so no counterfactual meets a coupling that the
    team misses, and leaving out an agent not in range changes nothing: the coupling is
    counted again only without each agent in range (O(R) a POI, not O(R^2)). ``near`` is
    ``state.in_range[t, e]``, the team's view, passed in rather than made again per POI;
    ``count`` (K,) its sums over the agents (``state.poi_counts[e]``), from which an untyped
    POI's coupling is read in O(1): ``coupling_met`` without agent i is ``count[k] -
    near[i, k] >= n_req[k]`` there, the same integers (2026-12-06,
    ``benchmarks/configs/chain.toml``: ``score_team`` took twice the paper's time, ~0.9 ms a
    D generation more, its hottest loop that O(R) count per POI and step)."""
    is_typed = typed[k]
    if not (coupling_met(k, near, typed, require, agent_class, n_req, -1) if is_typed
            else count[k] >= n_req[k]):  # fmt: skip
        return
    if not captured[e, k] and predecessors_before(after, k, capture_step[e], t):
        capture_step[e, k] = t
        captured[e, k] = True
    for i in range(near.shape[0]):
        if captured_without[e, i, k]:
            continue
        if near[i, k] and not (coupling_met(k, near, typed, require, agent_class, n_req, i)
                               if is_typed else count[k] - 1 >= n_req[k]):  # fmt: skip
            continue
        if predecessors_before(after, k, step_without[e, i], t):
            captured_without[e, i, k] = True
            step_without[e, i, k] = t


@jit_inline
def nearest_value(positions, px, py, counts, n, without, failures=None, e=0, t=0):
    """The lab's distance value of a POI at (``px``, ``py``) whose coupling is met:
    ``n x prod_j 1 / max(1, d_j)`` over the ``n`` smallest distances d_j, world units, from
    ``positions`` (R, 2) of the agents i with ``counts[i]`` (in range or not), agent
    ``without`` left out (-1: none), multiplied nearest first (AADILab/influence-shaping
    ``custom_env.py``, ``AbstractRoverConstraint._step_is_satisfied``: a stable sort, so ties
    go by agent index); 0 if fewer than ``n`` agents count. With ``failures``, the agents of
    team ``e`` not alive at state ``t`` do not count. Selection without a buffer, ``n``
    passes over the agents: O(n R)."""
    value = float(n)
    last_d, last_i = -1.0, -1
    for _ in range(n):
        best_d, best_i = np.inf, -1
        for i in range(positions.shape[0]):
            if i == without or not counts[i] or not alive(failures, e, t, i):
                continue
            dx = positions[i, 0] - px
            dy = positions[i, 1] - py
            d = np.sqrt(dx * dx + dy * dy)
            after_last = d > last_d or (d == last_d and i > last_i)
            if after_last and (d < best_d or (d == best_d and best_i < 0)):
                best_d, best_i = d, i
        if best_i < 0:
            return 0.0
        value = value * 1.0 / max(1.0, best_d)
        last_d, last_i = best_d, best_i
    return value


@jit_inline
def distance_value(e, k, state, rules, n, without, failures, t):
    """:func:`nearest_value` of POI k of team e at step t, over the agents that count for
    it (``rules.counts_for[k]``) and are alive, agent ``without`` left out (-1: none)."""
    return nearest_value(state.rover_positions[e], state.poi_positions[e, k, 0],
                         state.poi_positions[e, k, 1], rules.counts_for[k], n, without,
                         failures, e, t)  # fmt: skip


@jit_inline
def score_by_distance(e, k, near, state, rules, n_req, t, failures=None):
    """A distance-valued POI k of team e at scored step t (its ``final_only`` already
    checked): its value, and without each agent, where the coupling is met (a count under
    ``n_req``, or a typed one), kept at their best over the steps; the POI counts as
    captured from the first step its value is positive. Leaving out an agent that is not
    among the ``n`` nearest changes nothing, but the nearest are not known before they are
    found, so each counterfactual is valued again: O(n R^2) at a step the coupling is met."""
    if not coupling_met(k, near, rules.typed, rules.require, rules.agent_class, n_req, -1):
        return
    n = n_req[k]
    value = distance_value(e, k, state, rules, n, -1, failures, t)
    if value > rules.value_best[e, k]:
        rules.value_best[e, k] = value
    if value > 0.0 and not state.captured[e, k]:
        state.capture_step[e, k] = t
        state.captured[e, k] = True
    for i in range(near.shape[0]):
        if not rules.counts_for[k, i]:  # never among its agents: the same value
            without = value
        elif near[i, k] and not coupling_met(
            k, near, rules.typed, rules.require, rules.agent_class, n_req, i
        ):
            without = 0.0
        else:
            without = distance_value(e, k, state, rules, n, i, failures, t)
        if without > rules.value_without[e, i, k]:
            rules.value_without[e, i, k] = without
        if without > 0.0:
            state.captured_without[e, i, k] = True


@jit_inline
def coupling_met(k, near, typed, require, agent_class, n_req, without):
    """Eq. 12 for POI k from one step's in-range agents ``near`` (R, K) bool, agent
    ``without`` left out (-1: none): ``n_req[k]`` of them, or for a typed POI (``typed[k]``)
    at least ``require[k, c]`` of each class c (``agent_class`` (R,)); the arrays are
    :class:`~physrover.domain.scoring.rules.PoiRules`' (:func:`capture_by_rules` says why
    they come one by one)."""
    is_typed = typed[k]
    for c in range(require.shape[1] if is_typed else 1):
        need = require[k, c] if is_typed else n_req[k]
        n = 0
        for i in range(near.shape[0]):  # branch-free: who is in range is a coin toss
            n += np.int64((i != without) & near[i, k] & ((not is_typed) | (agent_class[i] == c)))
        if n < need:
            return False
    return True


@jit
def score(state, d_cap, n_req, t, rules=None, counted=None):
    """Score step ``t`` (0 after reset, then 1, 2, ...) of every team in ``state``: the POIs'
    agent counts and which agents are in range (``in_range[t]``), captures (Eqs. 12-13)
    under each POI's coupling ``n_req`` (K,) int64, G so far (Eq. 11) and the captures
    without each agent (the counterfactual of D, Eq. 1); ``rules``, ``counted``:
    :func:`score_team`'s."""
    for e in range(state.cos_h.shape[0]):
        score_team(e, state, d_cap * d_cap, n_req, t, rules, counted)


__all__ = ["capture_by_rules", "coupling_met", "distance_value", "last_scored_step",
           "nearest_value", "predecessors_before", "score", "score_by_distance",
           "score_team"]  # fmt: skip
