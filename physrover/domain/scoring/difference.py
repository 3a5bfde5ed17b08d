"""G from an episode's captures (Eq. 11) and the counterfactual credits read from them:
D (Eq. 1) and D++.

- Eq. 11: ``G = sum_k V_k max_t I_kt``: each POI counts once, whenever it was captured;
- Eq. 1 with the null counterfactual (paper Section 4.2): ``D_i = G(z) - G(z_-i)``, where
  ``z_-i`` removes rover i's whole trajectory: a POI counts for ``G(z_-i)`` if at some
  scored step its coupling is met *without* rover i;
- beyond the paper, :func:`step_credits`: G, D or D++ of every step taken alone (a critic's
  per-step target, ``[learn] critic_target = "step"``), :func:`partial_difference`, an
  exploration credit for episodes without a capture, and :func:`regret`, what a rover
  would have added standing where it was needed most (feedback "D-regret" is D less it).

The compiled step (:func:`physrover.domain.scoring.captures.score_team`) keeps the captures
with and without each rover in the world's :class:`~physrover.domain.state.WorldState`, so
D is read off at any step (O(E R K)); the per-step record ``in_range`` (O(T E R K) bools,
0.2 MB at paper scale) is what D++ replays.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


def team_score(captured: np.ndarray, poi_values: np.ndarray) -> np.ndarray:
    """Eq. 11: (..., K) ever-captured mask and (E, K) or (K,) values -> (...) score G.

    ``captured`` may carry extra axes between team and POI (e.g. (E, R, K) for G(z_-i)).
    """
    values = np.asarray(poi_values, dtype=np.float64)
    if values.ndim == 2 and captured.ndim == 3:
        values = values[:, None, :]
    return (captured * values).sum(axis=-1)


def difference(state, rules=None) -> np.ndarray:
    """(E, R) difference evaluation of every rover so far (Eq. 1, null counterfactual);
    ``rules`` (:class:`~physrover.domain.scoring.rules.PoiRules`, if the world has them)
    give the POIs valued by distance their best value without each rover."""
    if rules is None or not rules.valued.any():
        return state.score[:, None] - team_score(state.captured_without, state.poi_values)
    valued = rules.valued
    without = team_score(state.captured_without & ~valued, state.poi_values)
    without += (rules.value_without * (state.poi_values * valued)[:, None, :]).sum(axis=-1)
    return state.score[:, None] - without


def d_plus_plus(state, n_req: np.ndarray) -> np.ndarray:
    """(E, R) D++ of every rover (Rahmattalabi, Chung, Colby and Tumer 2016, Algorithm 1).

    ``D++_i(n) = (G(z + n z_i) - G(z)) / n`` is the gain per partner of adding ``n`` copies
    of rover i's whole trajectory (counterfactual partners at its positions at every step);
    a POI counts for ``G(z + n z_i)`` if at some scored step the rovers in range of it,
    plus n if rover i was in range, reach its coupling. With ``N = max_k n_req_k - 1``
    partners (enough to complete any POI rover i visited alone):

    - if ``D++_i(N) <= D_i``, D++ is D_i (the rover gains nothing from partners);
    - else D++ is ``D++_i(n)`` for the smallest n in 1..N with ``D++_i(n) > D_i``.

    The lab's later code (zerbeln/RoverDomain) differs: it divides by ``n + 1`` and keeps
    the largest value over n; this is the published algorithm. With ``n_req = 1`` (N = 0)
    D++ is D. Reads the episode's record ``state.in_range`` (T + 1, E, R, K) and G, D.
    """
    D = difference(state)
    partners = int(np.max(n_req)) - 1
    if partners < 1:
        return D
    near = state.in_range  # (T + 1, E, R, K)
    count = near.sum(axis=2, dtype=np.int32)  # (T + 1, E, K): rovers near each POI
    # With n copies of rover i, POI k counts if it was captured anyway, or if at a step
    # where rover i was near it the rovers near it plus n reach its coupling: so only the
    # most rovers near k at a step rover i was near matters (0: never near, as copies of a
    # rover that never came near add nobody).
    most = np.where(near, count[:, :, None, :], 0).max(axis=0)  # (E, R, K)
    was_near = near.any(axis=0)  # (E, R, K)
    captured = state.captured[:, None, :]  # (E, 1, K)
    G = state.score[:, None]  # (E, 1)
    values = state.poi_values[:, None, :]  # (E, 1, K)
    gains = {}
    for n in range(1, partners + 1):
        with_n = captured | (was_near & (most + n >= n_req))  # (E, R, K)
        gains[n] = ((with_n * values).sum(-1) - G) / n
    result = D.copy()
    undecided = gains[partners] > D  # else D++ is D
    for n in range(1, partners + 1):
        take = undecided & (gains[n] > D)
        result[take] = gains[n][take]
        undecided &= ~take
    return result


class _Steps(NamedTuple):
    """Each step of an episode taken alone as an episode of one scored step: the fields of
    :class:`~physrover.domain.state.WorldState` that :func:`difference` and
    :func:`d_plus_plus` read, with the (step, team) pairs as the teams."""

    in_range: np.ndarray  # (1, S E, R, K)
    captured: np.ndarray  # (S E, K)
    captured_without: np.ndarray  # (S E, R, K)
    score: np.ndarray  # (S E,)
    poi_values: np.ndarray  # (S E, K)


def step_credits(state, n_req: np.ndarray, signal: str) -> np.ndarray:
    """(T + 1, E, R) the credit ``signal`` ("G", "D" or "D++") of every rover at each step
    t taken alone: the credit of a one-step episode whose only scored step is t, so G_t is
    ``sum_k V_k I_kt`` (Eq. 11 with the max over t dropped), D_t = G_t minus G_t without
    rover i (Eq. 1) and D++_t the same rule as :func:`d_plus_plus` with partners at step t.

    Beyond the paper (issue 46, lever 1): the per-pair target of a critic fitted step by step
    (``[learn] critic_target = "step"``), non-zero at the steps where a rover is near a POI
    (D++: even before a coupling forms), where the episode's D is the same number for every
    pair. Reads ``state.in_range`` (T + 1, E, R, K), ``state.poi_values`` and each POI's
    ``n_req`` (K,); for POIs not scored by a rule (every step scored alike, Eq. 12).
    """
    near = np.asarray(state.in_range)
    steps, n_teams, n_rovers, n_pois = near.shape
    flat = near.reshape(steps * n_teams, n_rovers, n_pois)
    values = np.broadcast_to(state.poi_values, (steps, n_teams, n_pois))
    values = values.reshape(steps * n_teams, n_pois)
    count = flat.sum(axis=1, dtype=np.int64)  # (S E, K)
    captured = count >= n_req
    if signal == "G":
        score = team_score(captured, values)
        return np.repeat(score.reshape(steps, n_teams)[..., None], n_rovers, axis=-1)
    alone = _Steps(
        in_range=flat[None],
        captured=captured,
        captured_without=(count[:, None, :] - flat) >= n_req,
        score=team_score(captured, values),
        poi_values=values,
    )
    if signal == "D":
        credit = difference(alone)
    elif signal == "D++":
        credit = d_plus_plus(alone, n_req)
    else:
        raise ValueError(f"step credits are G, D or D++, not {signal!r}")
    return credit.reshape(steps, n_teams, n_rovers)


def partial_difference(state, n_req: np.ndarray) -> np.ndarray:
    """(E, R) the partial-coupling credit: D where the team captured something, else the
    difference each rover makes to how near the team came to its couplings.

    Beyond the paper (issue 46, lever 4: an exploration credit that is not 0 while D is,
    and gives way to D once captures occur). A POI's *progress* is the largest fraction of
    its coupling met at one scored step, ``p_k = max_t min(1, c_kt / n_req_k)`` with
    ``c_kt`` the rovers within its capture radius (Eq. 13); the soft score is ``sum_k V_k
    p_k``; rover i's partial credit is the soft score minus the soft score without rover
    i's trajectory (Eq. 1's null counterfactual on the soft score). In an episode with G >
    0 the credit is D itself, so a team that captures is credited exactly as the paper's.
    A rover alone at a POI of value V with coupling n earns V / n; each partner it joins
    adds to the progress its presence makes. Reads ``state.in_range`` (T + 1, E, R, K),
    the values and G; POIs without rules (every step scored alike).
    """
    near = np.asarray(state.in_range)  # (T + 1, E, R, K)
    need = np.asarray(n_req, dtype=np.float64)
    count = near.sum(axis=2, dtype=np.int64)  # (T + 1, E, K)
    progress = np.minimum(1.0, count / need).max(axis=0)  # (E, K)
    without = np.minimum(1.0, (count[:, :, None, :] - near) / need).max(axis=0)  # (E, R, K)
    values = state.poi_values
    soft = (progress * values).sum(-1)[:, None] - (without * values[:, None, :]).sum(-1)
    return np.where(state.score[:, None] > 0, difference(state), soft)


def regret(state, n_req: np.ndarray) -> np.ndarray:
    """(E, R) each rover's regret: how much more G the team would have scored had the
    rover, instead of its trajectory, stood at one POI at one scored step.

    Beyond the paper (issue 46: trained teams crowd the most valuable POI, where a surplus
    rover's D is 0, while the next POI is one rover short; ``experiments/plateau_reading.py``).
    Rover i *relocated* to POI k is in range of k, and of nothing else, at the scored step
    where most of the other rovers were in range of k: with ``c_kt(-i)`` the rovers other
    than i in range of POI k at step t, the team scores
    ``G_k(i) = G(z_-i) + V_k [k not captured without i, and max_t c_kt(-i) + 1 >= n_req_k]``
    (``G(z_-i)``: D's null counterfactual, Eq. 1). The regret is
    ``max(0, max_k G_k(i) - G(z))``: 0 for a rover that was where it was needed; V for a
    rover in surplus at a captured POI while another POI of value V was one rover short;
    0 for a rover whose absence loses a capture worth more than any it could complete.
    Reads ``state.in_range`` (T + 1, E, R, K; the unscored states hold no one), the
    captures without each rover, G and each POI's ``n_req`` (K,); POIs without rules.
    """
    near = np.asarray(state.in_range)  # (T + 1, E, R, K)
    count = near.sum(axis=2, dtype=np.int64)  # (T + 1, E, K)
    best_without = (count[:, :, None, :] - near).max(axis=0)  # (E, R, K): most others at k
    values = np.asarray(state.poi_values, dtype=np.float64)  # (E, K)
    completes = ~state.captured_without & (best_without + 1 >= np.asarray(n_req))
    relocated = team_score(state.captured_without, values)
    relocated = relocated + (completes * values[:, None, :]).max(axis=-1)  # (E, R)
    return np.maximum(0.0, relocated - state.score[:, None])
