"""POIs that leave every agent's sight (``[[pois]] disappear``): which, and from when.

A POI's ``disappear`` rule (:mod:`physrover.config.pois`) marks it *gone*
(``WorldState.gone``, (E, K) bool, cleared at reset) once its condition holds; the lidar
senses no gone POI (:func:`~physrover.domain.sensing.lidar.lidar_agent`), and scoring never
reads the mark. :func:`vanish_team` runs in the step before anyone senses
(:mod:`physrover.domain.step`), from the state just reached:

- ``"captured"``: gone once captured, that is from the step after its capture (the step
  senses before it scores);
- ``"visited"``: gone from the first state at which an agent of ``visited_by`` (default:
  every class that captures), alive, is within ``visit_radius`` of it and within the
  radius of its own sensor. The lab's ``disappear_bool`` (AADILab/influence-shaping,
  ``lidar.hpp`` SmartLidar::scan, at 8a71aa8): a rover whose scan finds a hidden POI
  within 1.0 and within its observation radius sets it observed, and every later scan
  skips it; the lab scans its rovers before its UAVs, so the UAVs of the same state
  already miss it, as here, where the marks are made before any agent senses.

:class:`Vanishing` is the step plan's ``vanish`` part, None (compiled away) when every POI
is always in sight.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import types
from numba.extending import overload

from physrover.config.pois import DISAPPEAR
from physrover.core.compiled import jit_inline
from physrover.domain.agents.classes import agent_classes, class_names, class_sensor
from physrover.domain.agents.failures import alive

NEVER, CAPTURED, VISITED = 0, 1, 2
"""``Vanishing.mode`` codes, in :data:`physrover.config.pois.DISAPPEAR` order."""


class Vanishing(NamedTuple):
    """The POIs' sight rules of a world (module docstring)."""

    mode: np.ndarray
    """(K,) int64: ``NEVER``, ``CAPTURED`` or ``VISITED`` (this module's codes)."""
    reach_sq: np.ndarray
    """(R, K) float64: agent i marks POI k "visited" within this squared distance,
    ``min(visit_radius, its sensor's radius)^2``; -1 where it never does."""

    @classmethod
    def build(cls, config) -> Vanishing | None:
        """The rules of ``config`` (a DomainConfig), None if no POI ever leaves sight."""
        pois = config.pois
        if all(p.disappear == "never" for p in pois):
            return None
        mode = np.array([DISAPPEAR.index(p.disappear) for p in pois], dtype=np.int64)
        names = class_names(config)
        classes = agent_classes(config)
        captures = [c.captures for c in config.agents] or [True]
        radius = [getattr(class_sensor(config, c), "radius", math.inf)
                  for c in range(len(names))]  # fmt: skip
        reach_sq = np.full((config.n_rovers, len(pois)), -1.0)
        for k, poi in enumerate(pois):
            if poi.disappear != "visited":
                continue
            for i, c in enumerate(classes):
                marks = names[c] in poi.visited_by if poi.visited_by else captures[c]
                if marks:
                    reach_sq[i, k] = min(poi.visit_radius, radius[c]) ** 2
        return cls(mode, reach_sq)


@jit_inline
def mark_gone(mode, reach_sq, e, t, state, failures):
    """Mark team e's POIs that leave sight at state t (module docstring), under the rules
    ``mode`` and ``reach_sq`` of a :class:`Vanishing`; ``failures`` the plan's."""
    positions, pois, gone = state.rover_positions, state.poi_positions, state.gone
    for k in range(mode.shape[0]):
        if gone[e, k] or mode[k] == NEVER:
            continue
        if mode[k] == CAPTURED:
            gone[e, k] = state.captured[e, k]
            continue
        for i in range(positions.shape[1]):
            if reach_sq[i, k] < 0.0 or not alive(failures, e, t, i):
                continue
            dx = positions[e, i, 0] - pois[e, k, 0]
            dy = positions[e, i, 1] - pois[e, k, 1]
            if dx * dx + dy * dy <= reach_sq[i, k]:
                gone[e, k] = True
                break


def vanish_team(vanishing, e, t, state, failures):
    """:func:`mark_gone` under ``vanishing``, a :class:`Vanishing`, or nothing if it is
    None (compiled away)."""
    if vanishing is not None:
        mark_gone(vanishing.mode, vanishing.reach_sq, e, t, state, failures)


@overload(vanish_team, inline="always")
def _vanish_team_compiled(vanishing, e, t, state, failures):
    if isinstance(vanishing, types.NoneType):
        return lambda vanishing, e, t, state, failures: None
    return lambda vanishing, e, t, state, failures: mark_gone(
        vanishing.mode, vanishing.reach_sq, e, t, state, failures
    )


__all__ = ["CAPTURED", "NEVER", "VISITED", "Vanishing", "mark_gone", "vanish_team"]
