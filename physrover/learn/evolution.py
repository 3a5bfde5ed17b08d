"""Selection and mutation: binary tournament with Cauchy mutation (paper Section 4.2), and the
lab's later n-elites tournament (:func:`evolve_elites`).

The scheme of the paper's lab's code, applied to every rover's population at once:

1. pair the k policies of a population at random (a fresh permutation; with k odd, the
   last policy of the permutation sits out and survives unchanged);
2. in each pair the policy with the higher fitness wins (ties broken at random); the loser
   is replaced by a copy of the winner, whose weights are each mutated with probability
   ``mutation_rate`` by adding a sample of the standard Cauchy distribution (times
   ``mutation_scale``);
3. winners survive unchanged, so the population size is constant and the best policy of
   a population is never lost. Fitness is maximised.

Each population's random draws come from the generator passed in.
"""

from __future__ import annotations

import numpy as np


def tournament_pairs(
    fitness: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Winners and losers of a random pairing of each population.

    Args:
        fitness: (R, k) fitness of each policy (NaN counts as worst).

    Returns:
        winners, losers: (R, k // 2) policy indices.
    """
    n_pop, k = fitness.shape
    order = np.argsort(rng.random((n_pop, k)), axis=1)  # one random permutation per rover
    a, b = order[:, 0 : k - 1 : 2], order[:, 1:k:2]
    fit = np.where(np.isnan(fitness), -np.inf, fitness)
    fa, fb = np.take_along_axis(fit, a, 1), np.take_along_axis(fit, b, 1)
    coin = rng.random(a.shape) < 0.5
    a_wins = (fa > fb) | ((fa == fb) & coin)
    return np.where(a_wins, a, b), np.where(a_wins, b, a)


def mutate(
    offspring: np.ndarray,
    rng: np.random.Generator,
    rate: float,
    scale: float,
    noise: str = "cauchy",
) -> None:
    """Add ``scale`` times standard Cauchy (or ``noise="gauss"``: normal) noise to each weight
    of ``offspring`` (..., P) with probability ``rate``, in place: one uniform draw per
    weight, then one noise draw per mutated weight, in C order."""
    hit = rng.random(offspring.shape) < rate
    n = int(hit.sum())
    draw = rng.standard_cauchy(n) if noise == "cauchy" else rng.standard_normal(n)
    offspring[hit] += (scale * draw).astype(offspring.dtype)


def evolve(
    genomes: np.ndarray,
    fitness: np.ndarray,
    rng: np.random.Generator,
    mutation_rate: float,
    mutation_scale: float = 1.0,
    noise: str = "cauchy",
) -> tuple[np.ndarray, np.ndarray]:
    """One generation of binary tournament + mutation (Cauchy: the paper's), in place.

    Args:
        genomes: (R, k, P) populations; losers are overwritten.
        fitness: (R, k).

    Returns:
        winners, losers: (R, k // 2) indices, as from :func:`tournament_pairs`.
    """
    winners, losers = tournament_pairs(fitness, rng)
    rows = np.arange(genomes.shape[0])[:, None]
    offspring = genomes[rows, winners]  # (R, k // 2, P) copies
    mutate(offspring, rng, mutation_rate, mutation_scale, noise)
    genomes[rows, losers] = offspring
    return winners, losers


def evolve_elites(
    pool: np.ndarray,
    pool_fitness: np.ndarray,
    k: int,
    n_elites: int,
    rng: np.random.Generator,
    mutation_rate: float,
    mutation_scale: float,
    noise: str = "gauss",
    pool_team_G: np.ndarray | None = None,
    n_team_fitness: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """The lab's n-elites binary tournament (``generate_offspring`` in its ``ccea_lib.py``).

    Each population's next k policies are drawn from its pool (the k current policies, then
    the members of the elite teams, :mod:`physrover.learn.team_elites`):

    1. the ``n_elites`` fittest pool members, best first, copied unmutated (ties: lower pool
       index first), so the champion, the best, is policy 0;
    1b. the ``n_team_fitness`` pool members with the best ``pool_team_G`` (R, n), the G of
       the team each played in (the lab's ``n_individual_elites_based_on_team_fitness``;
       ties as above; one may be a fitness elite too, as in the lab), copied unmutated;
    2. ``k - n_elites - n_team_fitness`` winners of binary tournaments, each between two
       distinct pool members drawn uniformly (the higher fitness wins, a fair coin breaks
       ties), copied and mutated (:func:`mutate`).

    NaN fitness counts as worst. The lab lists each current policy twice in the pool (once
    in the population, once as a member of its ad-hoc team); here each appears once.

    Args:
        pool: (R, n, P) genomes, n >= 2.
        pool_fitness: (R, n) their fitness.

    Returns:
        genomes: (R, k, P) the next populations.
        carried: (R, k) the fitness each new policy carries (the elites' own, NaN for the
            mutated offspring, which no episode has scored yet).
    """
    n_pop, n = pool_fitness.shape
    fit = np.where(np.isnan(pool_fitness), -np.inf, pool_fitness)
    rows = np.arange(n_pop)[:, None]
    best = np.argsort(-fit, axis=1, kind="stable")[:, :n_elites]  # (R, n_elites)
    if n_team_fitness:
        team_fit = np.where(np.isnan(pool_team_G), -np.inf, pool_team_G)
        by_team = np.argsort(-team_fit, axis=1, kind="stable")[:, :n_team_fitness]
        best = np.concatenate([best, by_team], axis=1)
    n_tour = k - best.shape[1]
    a = rng.integers(n, size=(n_pop, n_tour))
    b = rng.integers(n - 1, size=(n_pop, n_tour))
    b += b >= a  # a second member, distinct from the first
    fa, fb = fit[rows, a], fit[rows, b]
    coin = rng.random(a.shape) < 0.5
    winners = np.where((fa > fb) | ((fa == fb) & coin), a, b)
    offspring = pool[rows, winners]  # (R, n_tour, P) copies
    mutate(offspring, rng, mutation_rate, mutation_scale, noise)
    genomes = np.concatenate([pool[rows, best], offspring], axis=1)
    carried = np.concatenate([pool_fitness[rows, best], np.full((n_pop, n_tour), np.nan)], 1)
    return genomes, carried
