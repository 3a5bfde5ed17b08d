"""Team score G (Eqs. 11-14) and difference evaluations D (Eq. 1), batched over teams.

- Eq. 13: rover i is in range of POI k at step t when ``delta_ikt^2 <= d_cap^2``, with the
  bounded distance ``delta = max(||p_i - p_k||, d_min)`` of Eq. 14.
- Eq. 12: POI k is captured at step t when at least ``n_req`` rovers are in range of it.
- Eq. 11: ``G = sum_k V_k max_t I_kt``: each POI counts once, whenever it was captured.
- Eq. 1 with the null counterfactual (paper Section 4.2): ``D_i = G(z) - G(z_-i)``, where
  ``z_-i`` removes rover i's whole trajectory: a POI counts for ``G(z_-i)`` if at some step at
  least ``n_req`` rovers *other than i* were in range of it.

Steps are scored after reset and after every environment step (``steps + 1`` times), by the
compiled :func:`physrover.domain.kernels.score` into the scoring arrays of the world's
:class:`~physrover.domain.state.WorldState`; memory is O(E R K), not O(T E R K): D is
tracked online, through ``captured_without``.
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


def start_episode(state) -> None:
    """Forget every capture in ``state`` (a :class:`~physrover.domain.state.WorldState`):
    the start of an episode, before step 0 is scored."""
    state.poi_counts[:] = 0
    state.captured[:] = False
    state.captured_without[:] = False
    state.capture_step[:] = -1
    state.score[:] = 0.0


def difference(state) -> np.ndarray:
    """(E, R) difference evaluation of every rover so far (Eq. 1, null counterfactual)."""
    return state.score[:, None] - team_score(state.captured_without, state.poi_values)
