"""POI rules as the compiled scoring reads them (``[[pois]]``, :mod:`physrover.config.pois`,
and which agent classes count, ``[[agents]]``).

:class:`PoiRules` holds the rules of a domain's K POIs as arrays, with the one piece of
episode state they need, and :func:`physrover.domain.scoring.captures.score_team` takes it as its
``rules`` argument (None, the paper's POIs, compiles the rules away). With rules, POI k is
captured at a scored step t (Eq. 12, generalised) iff

- at least ``n_req[k]`` rovers are within ``capture_radius[k]`` of it (Eq. 13 with its own
  radius, or under ``capture_by`` each agent's own: ``capture_radius_sq[k, i]``; the
  in-range record ``in_range`` uses that radius too), or for a typed POI
  (``require = {class = count}``) at least that many agents of each named class (and only
  they are in its range);
- every POI j in ``after[k]`` was captured at a step before t (so a chain of POIs takes at
  least a step per link, and the order is decided by steps, not by POI index);
- ``score_at[k]`` is ``"any"``, or t is the last scored step (``steps``, or ``steps - 1``
  under ``scored_states = "before-steps"``).

G is Eq. 11 over these captures, but for a POI valued by distance (``value_by =
"distance"``, :mod:`physrover.config.pois`), which adds V_k times its best (or final)
distance value ``value_best``. D (Eq. 1) applies the same rules to each counterfactual:
without rover i, POI k counts at t only if its predecessors were captured without rover i
before t (``step_without``, the counterfactual's first capture steps), and a distance-valued
POI adds its best value without rover i, ``value_without``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from physrover.config.pois import capture_radii
from physrover.domain.agents.classes import (
    agent_classes,
    class_names,
    counted_agents,
    sensor_radius,
)
from physrover.domain.scoring.captures import last_scored_step


class PoiRules(NamedTuple):
    """The rules of K POIs for E teams of R rovers (module docstring)."""

    capture_radius_sq: np.ndarray
    """(K, R) float64: the distance squared, world units^2, within which agent i is in
    POI k's range: its capture radius, or under ``capture_by = "sight"`` the smaller of the
    agent's sensing radius and the POI's ``sense_radius`` (the larger of the two rules'
    radii for ``"radius-or-sight"``; inf: any distance)."""
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
    """(R,) bool: the agents that count toward couplings (their class ``captures``)."""
    counts_for: np.ndarray
    """(K, R) bool: the agents that count for POI k: ``counted``, or for a typed POI the
    agents of the classes it requires; the others are never in its range (``in_range``
    False), so a UAV's D is 0 wherever it does not count."""
    typed: np.ndarray
    """(K,) bool: the POI requires counts by class (``require``) instead of ``n_req``."""
    require: np.ndarray
    """(K, C) int64: agents of class c that a typed POI needs at one step (0: none)."""
    agent_class: np.ndarray
    """(R,) int64: each agent's class."""
    valued: np.ndarray
    """(K,) bool: the POI is valued by the distances of its agents (``value_by =
    "distance"``), not by a capture."""
    value_best: np.ndarray
    """(E, K) float64: a distance-valued POI's best value so far (episode state)."""
    value_without: np.ndarray
    """(E, R, K) float64: the same without agent i, D's counterfactual (episode state)."""

    @classmethod
    def build(cls, config, n_teams: int, always: bool = False) -> PoiRules | None:
        """The rules of ``config`` (a :class:`~physrover.config.DomainConfig`) for
        ``n_teams`` teams, or None without ``[[pois]]`` and ``[[agents]]`` (the paper's
        POIs and rovers) unless ``always`` (the rules that are the paper's)."""
        if not (config.pois or config.agents or always):
            return None
        k = config.n_pois
        pois = config.pois or [None] * k
        radius = _capture_radii_sq(config)
        after = np.zeros((k, k), dtype=bool)
        for i, p in enumerate(pois):
            after[i, list(p.after if p else ())] = True
        final = np.array([bool(p) and p.score_at == "final" for p in pois], dtype=bool)
        t_final = last_scored_step(config)
        without = np.full((n_teams, config.n_rovers, k), -1, dtype=np.int64)
        counted = counted_agents(config)
        agent_class = agent_classes(config)
        names = class_names(config)
        require = np.zeros((k, len(names)), dtype=np.int64)
        for i, p in enumerate(pois):
            for name, n in (p.require if p else {}).items():
                require[i, names.index(name)] = n
        typed = require.any(axis=1)
        counts_for = np.where(typed[:, None], require[:, agent_class] > 0, counted[None, :])
        valued = np.array([bool(p) and p.value_by == "distance" for p in pois], dtype=bool)
        return cls(radius, after, final, int(t_final), without, counted, counts_for, typed,
                   require, agent_class, valued, np.zeros((n_teams, k)),
                   np.zeros((n_teams, config.n_rovers, k)))  # fmt: skip

    def start(self, teams: np.ndarray | None = None) -> None:
        """Forget the counterfactual captures and the distance values: the start of an
        episode (of the ``teams``, an (E,) bool mask, only, if given)."""
        if teams is None:
            teams = slice(None)
        self.step_without[teams] = -1
        self.value_best[teams] = 0.0
        self.value_without[teams] = 0.0


def _capture_radii_sq(config) -> np.ndarray:
    """(K, R) :attr:`PoiRules.capture_radius_sq` of a domain."""
    own = np.array(capture_radii(config), dtype=np.float64)
    sensing = np.array([sensor_radius(config, c) for c in agent_classes(config)])
    radius = np.repeat(own[:, None], config.n_rovers, axis=1)
    for k, poi in enumerate(config.pois):
        sight = np.minimum(sensing, poi.sense_radius)
        if poi.capture_by == "sight":
            radius[k] = sight
        elif poi.capture_by == "radius-or-sight":
            radius[k] = np.maximum(radius[k], sight)
    return radius * radius
