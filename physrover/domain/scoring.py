"""Team score G (Eqs. 11-14) and difference evaluations D (Eq. 1), batched over teams.

- Eq. 13: rover i is in range of POI k at step t when ``delta_ikt^2 <= d_cap^2``, with the
  bounded distance ``delta = max(||p_i - p_k||, d_min)`` of Eq. 14.
- Eq. 12: POI k is captured at step t when at least ``n_req`` rovers are in range of it.
- Eq. 11: ``G = sum_k V_k max_t I_kt``: each POI counts once, whenever it was captured.
- Eq. 1 with the null counterfactual (paper Section 4.2): ``D_i = G(z) - G(z_-i)``, where
  ``z_-i`` removes rover i's whole trajectory: a POI counts for ``G(z_-i)`` if at some step at
  least ``n_req`` rovers *other than i* were in range of it.

Steps are scored after reset and after every environment step (``steps + 1`` times).
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


class ScoreKeeper:
    """The captures of an episode for E teams, and G and D at any step.

    :meth:`reset` starts an episode; the world's compiled kernels
    (:func:`physrover.domain.kernels.observe_and_score`) advance the arrays after reset and
    after every step, and the world counts the steps in ``t``. Memory is O(E R K), not
    O(T E R K): D is tracked online, through ``captured_without``.
    """

    def __init__(self, n_req: int):
        self.n_req = n_req
        self.captured: np.ndarray | None = None  # (E, K) bool: captured at some step so far
        self.captured_without: np.ndarray | None = None  # (E, R, K) bool: same, rover i removed
        self.capture_step: np.ndarray | None = None  # (E, K) int: first capture step, -1 if none
        self.poi_values: np.ndarray | None = None  # (E, K)
        self.score: np.ndarray | None = None  # (E,) float64: G so far, updated every step
        self.t = 0

    def reset(self, n_teams: int, n_rovers: int, poi_values: np.ndarray) -> None:
        n_pois = poi_values.shape[-1]
        self.poi_values = np.broadcast_to(poi_values, (n_teams, n_pois)).astype(np.float64)
        self.captured = np.zeros((n_teams, n_pois), dtype=bool)
        self.captured_without = np.zeros((n_teams, n_rovers, n_pois), dtype=bool)
        self.capture_step = np.full((n_teams, n_pois), -1, dtype=np.int64)
        self.score = np.zeros(n_teams)
        self.t = 0

    @property
    def G(self) -> np.ndarray:
        """(E,) team score so far (Eq. 11), a copy."""
        return self.score.copy()

    @property
    def D(self) -> np.ndarray:
        """(E, R) difference evaluation of every rover so far (Eq. 1, null counterfactual)."""
        return self.score[:, None] - team_score(self.captured_without, self.poi_values)
