"""Compiled draws of the scenarios' random POI layouts, every team's from its own generator.

A kernel here reads each team's ``numpy.random.Generator`` through
:mod:`physrover.core.streams`: the doubles ``rng.random()`` would give, in the same order,
so a layout is the one a plain loop over the team's generator draws (the oracle in
``tests/test_layouts.py``), and the generator goes on from where the layout left it. One
call draws every team's layout (the loop over E generators in Python cost about 0.8 ms a
reset of 60 teams).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from physrover.core.compiled import jit
from physrover.core.streams import next_double, stream_handles


@jit
def _uniform_layouts(handles, half, gap, max_tries, out):
    """Fill ``out`` (E, K, 2) with team e's POIs from stream ``handles[e]``; returns the
    first team with no layout after ``max_tries`` attempts, or -1. A POI is two doubles
    u, v mapped to (half (2u - 1), half (2v - 1)), redrawn until its squared distance to
    each POI before it is at least ``gap`` squared; after ``max_tries`` failed draws of one
    POI the layout starts again."""
    n_teams, k = out.shape[0], out.shape[1]
    gap2 = gap * gap
    for e in range(n_teams):
        placed = 0
        for _ in range(max_tries):
            placed = 0
            while placed < k:
                found = False
                x = y = 0.0
                for _ in range(max_tries):
                    u = next_double(handles[e])
                    v = next_double(handles[e])
                    x, y = half * (2.0 * u - 1.0), half * (2.0 * v - 1.0)
                    found = True
                    for j in range(placed):
                        dx, dy = out[e, j, 0] - x, out[e, j, 1] - y
                        if dx * dx + dy * dy < gap2:
                            found = False
                            break
                    if found:
                        break
                if not found:
                    break  # no room for this POI: start the layout again
                out[e, placed, 0], out[e, placed, 1] = x, y
                placed += 1
            if placed == k:
                break
        if placed < k:
            return e
    return -1


def uniform_layouts(
    rngs: Sequence[np.random.Generator], k: int, half: float, gap: float, max_tries: int
) -> np.ndarray:
    """(E, K, 2) POIs uniform in the square [-half, half]^2, at least ``gap`` apart, team e's
    drawn from ``rngs[e]`` alone (:class:`~physrover.domain.scenarios.Uniform`): each POI
    redrawn until it is ``gap`` from those before it (squared distances compared, exact in
    floating point); after ``max_tries`` failed draws of one POI the whole layout starts
    again, up to ``max_tries`` times. Raises RuntimeError if a team finds no layout."""
    out = np.empty((len(rngs), int(k), 2), dtype=np.float64)
    failed = _uniform_layouts(stream_handles(rngs), float(half), float(gap), int(max_tries), out)
    if failed >= 0:
        raise RuntimeError(
            f"uniform scenario: no layout of {k} POIs {gap} apart in {max_tries} attempts; "
            f"lower min_separation or raise half_size"
        )
    return out
