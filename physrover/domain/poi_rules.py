"""POI rules as the compiled scoring reads them (``[[pois]]``, :mod:`physrover.config.pois`,
and which agent classes count, ``[[agents]]``).

:class:`PoiRules` holds the rules of a domain's K POIs as arrays, with the one piece of
episode state they need, and :func:`physrover.domain.kernels.score_team` takes it as its
``rules`` argument (None, the paper's POIs, compiles the rules away). With rules, POI k is
captured at a scored step t (Eq. 12, generalised) iff

- at least ``n_req[k]`` rovers are within ``capture_radius[k]`` of it (Eq. 13 with its own
  radius; the in-range record ``in_range`` uses that radius too);
- every POI j in ``after[k]`` was captured at a step before t (so a chain of POIs takes at
  least a step per link, and the order is decided by steps, not by POI index);
- ``score_at[k]`` is ``"any"``, or t is the last scored step (``steps``, or ``steps - 1``
  under ``scored_states = "before-steps"``).

G is Eq. 11 over these captures. D (Eq. 1) applies the same rules to each counterfactual:
without rover i, POI k counts at t only if its predecessors were captured without rover i
before t (``step_without``, the counterfactual's first capture steps).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class PoiRules(NamedTuple):
    """The rules of K POIs for E teams of R rovers (module docstring)."""

    capture_radius_sq: np.ndarray
    """(K,) float64: each POI's capture radius squared, world units^2."""
    after: np.ndarray
    """(K, K) bool: ``after[k, j]``, POI j must be captured before POI k counts (j < k)."""
    final_only: np.ndarray
    """(K,) bool: the POI counts only at the last scored step."""
    t_final: int
    """The last scored step."""
    step_without: np.ndarray
    """(E, R, K) int64: the first step POI k was captured without rover i, -1 if none yet
    (episode state: reset by :meth:`start`)."""
    counted: np.ndarray
    """(R,) bool: the agents that count toward couplings (their class ``captures``); the
    others are never in range (``in_range`` False), so their D is 0."""

    @classmethod
    def build(cls, config, n_teams: int) -> PoiRules | None:
        """The rules of ``config`` (a :class:`~physrover.config.DomainConfig`) for
        ``n_teams`` teams, or None without ``[[pois]]`` and ``[[agents]]`` (the paper's
        POIs and rovers)."""
        if not (config.pois or config.agents):
            return None
        k = config.n_pois
        pois = config.pois or [None] * k
        radius = np.array([p.capture_radius if p and p.capture_radius else config.d_cap
                           for p in pois], dtype=np.float64)  # fmt: skip
        after = np.zeros((k, k), dtype=bool)
        for i, p in enumerate(pois):
            after[i, list(p.after if p else ())] = True
        final = np.array([bool(p) and p.score_at == "final" for p in pois], dtype=bool)
        t_final = config.steps if config.scored_states == "all" else config.steps - 1
        without = np.full((n_teams, config.n_rovers, k), -1, dtype=np.int64)
        counted = np.repeat([c.captures for c in config.agents] or [True],
                            [c.count for c in config.agents] or [config.n_rovers])  # fmt: skip
        return cls(radius * radius, after, final, int(t_final), without, counted.astype(bool))

    def start(self) -> None:
        """Forget the counterfactual captures: the start of an episode."""
        self.step_without[:] = -1
