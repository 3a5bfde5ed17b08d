"""Team formation: which policy of each population plays in which team.

A generation's round is a permutation of every population: ``order[q, r, m]`` is the policy of
rover r in team m of round q, so every policy plays exactly once per round. The paper draws the
permutations uniformly (:meth:`physrover.learn.fitness.FitnessMethod.plan`, the default);
:func:`softmax_teams` is the later lab code's ``form_softmax_teams``, :func:`rank_teams` its
``form_shaped_teams`` (``fixed_teams``).
"""

from __future__ import annotations

import numpy as np


def softmax_teams(
    rng: np.random.Generator, fitness: np.ndarray, rounds: int, temperature: float = 1.0
) -> np.ndarray:
    """(rounds, R, k) team orders drawn by a softmax over each population's fitness.

    The lab's ``form_softmax_teams`` forms team 0, then team 1, ...: each team takes one
    policy per population, drawn with probability ``exp(f_p / tau)`` normalised over the
    policies not drawn yet, until every policy has played. That is a Plackett-Luce order of
    each population, which is drawn in one step here: sort the policies by ``f_p / tau`` plus
    independent standard Gumbel noise, largest first (the Gumbel-top-k identity). Good
    policies therefore tend to share the early teams, and the last team takes who is left.

    Args:
        rng: the run's team generator; one Gumbel draw of shape (rounds, R, k).
        fitness: (R, k) the fitness each policy carries (the previous generation's). NaN,
            a policy not yet scored, counts as 0, the lab's convention for ``None``.
        rounds: independent orders to draw (a method's training rounds).
        temperature: tau > 0, in fitness units (the lab's is 1).

    Returns:
        order: (rounds, R, k) int64, each ``order[q, r]`` a permutation of ``range(k)``.
    """
    f = np.nan_to_num(np.asarray(fitness, dtype=np.float64), nan=0.0) / temperature
    keys = f[None] + rng.gumbel(size=(rounds, *f.shape))
    return np.argsort(-keys, axis=-1, kind="stable")


def rank_teams(fitness: np.ndarray, rounds: int) -> np.ndarray:
    """(rounds, R, k) team orders by rank: team m takes the m-th best policy of every
    population (the lab's ``form_shaped_teams``: each population sorted by its fitness,
    largest first, ties in population order, as Python's stable ``sorted(reverse=True)``;
    NaN, a policy not yet scored, counts as 0, the lab's ``None``). Every round is the
    same order."""
    f = np.nan_to_num(np.asarray(fitness, dtype=np.float64), nan=0.0)
    order = np.argsort(-f, axis=-1, kind="stable")
    return np.broadcast_to(order, (rounds, *order.shape)).copy()


def team_genomes(table: np.ndarray, index: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(E, R, P) the genome each rover plays in each team, ``table[r, index[e, r]]``, from
    (R, K, P) genomes and (E, R) int indices < K.

    Written into ``out`` when it is a C-contiguous array of that shape and dtype, else
    into a new one (returned either way): a learner keeps the array from one generation to
    the next, since the operating system hands a fresh 1-2 MB array out page by page, a
    page fault per 4 KiB, about a millisecond a generation on the 15-agent mixed team.
    """
    n_rovers, k, size = table.shape
    n_teams = index.shape[0]
    if index.shape != (n_teams, n_rovers) or not (0 <= index.min() and index.max() < k):
        raise IndexError(f"team index of shape {index.shape} out of range for {k} genomes "
                         f"of {n_rovers} rovers")  # fmt: skip
    shape = (n_teams, n_rovers, size)
    if out is None or out.shape != shape or out.dtype != table.dtype or not out.flags.c_contiguous:
        out = np.empty(shape, dtype=table.dtype)
    rows = np.arange(n_rovers) * k + index  # rows of the flattened (R * K, P) table
    np.take(
        np.ascontiguousarray(table).reshape(n_rovers * k, size),
        rows.reshape(-1),
        axis=0,
        out=out.reshape(n_teams * n_rovers, size),
        mode="clip",
    )  # checked above
    return out
