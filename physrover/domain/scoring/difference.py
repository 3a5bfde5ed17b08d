"""G from an episode's captures (Eq. 11) and the counterfactual credits read from them:
D (Eq. 1) and D++.

- Eq. 11: ``G = sum_k V_k max_t I_kt``: each POI counts once, whenever it was captured;
- Eq. 1 with the null counterfactual (paper Section 4.2): ``D_i = G(z) - G(z_-i)``, where
  ``z_-i`` removes rover i's whole trajectory: a POI counts for ``G(z_-i)`` if at some
  scored step its coupling is met *without* rover i.

The compiled step (:func:`physrover.domain.scoring.captures.score_team`) keeps the captures
with and without each rover in the world's :class:`~physrover.domain.state.WorldState`, so
D is read off at any step (O(E R K)); the per-step record ``in_range`` (O(T E R K) bools,
0.2 MB at paper scale) is what D++ replays.
"""

from __future__ import annotations

import numpy as np


def team_score(captured: np.ndarray, poi_values: np.ndarray) -> np.ndarray:
    """Eq. 11: (..., K) ever-captured mask and (E, K) or (K,) values -> (...) score G.

    ``captured`` may carry extra axes between team and POI (e.g. (E, R, K) for G(z_-i)).
    """
    values = np.asarray(poi_values, dtype=np.float64)
    if values.ndim == 2 and captured.ndim == 3:
        values = values[:, None, :]
    return (captured * values).sum(axis=-1)


def difference(state) -> np.ndarray:
    """(E, R) difference evaluation of every rover so far (Eq. 1, null counterfactual)."""
    return state.score[:, None] - team_score(state.captured_without, state.poi_values)


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
