"""Team elites: the best teams found so far, kept whole and replayed (the lab's n-elites CCEA).

Under ``[learn] selection = "elites"`` with ``n_team_elites = n > 0``, the CCEA keeps n teams
as copied genomes, outside the populations (the lab's ``team_population``):

- every generation they play after the training teams, from the training teams' start
  state, so their G is measured afresh; only the training teams assign fitness (the lab's
  ``assign_agent_fitnesses`` on the ad-hoc teams);
- each elite member joins its population's selection pool
  (:func:`physrover.learn.evolution.evolve_elites`) with the fitness it had when its team
  became an elite: stale, as in the lab;
- then the n best teams by G among this generation's elite and training teams (ties: elites
  first, then lower index, the lab's stable sort) become the next elites, copied before
  evolution changes the populations.

Generation 1's elites are random picks from the populations (the lab's
``init_team_population``); they carry no fitness (NaN, worst in the pool) until a training
team replaces them.
"""

from __future__ import annotations

import numpy as np


class TeamElites:
    """n elite teams over R populations of k policies with P weights.

    Attributes:
        genomes: (n, R, P) each elite team's policies.
        fitness: (n, R) each member's fitness when its team became an elite (NaN: unknown).
        team_G: (n,) the G of each elite team when it became one (stale, as its members'
            fitness; NaN: unknown), what elites by team fitness read.
    """

    def __init__(self, n: int, population: np.ndarray, rng: np.random.Generator):
        """Random picks: ``population`` (R, k, P); one ``integers`` draw of shape (n, R)."""
        n_pop, k, _ = population.shape
        pick = rng.integers(k, size=(n, n_pop))
        self.genomes = population[np.arange(n_pop)[None, :], pick].copy()
        self.fitness = np.full((n, n_pop), np.nan)
        self.team_G = np.full(n, np.nan)

    @property
    def n(self) -> int:
        return self.genomes.shape[0]

    def table(self) -> np.ndarray:
        """(R, n, P): the elites as extra columns of the rollout's genome table."""
        return self.genomes.transpose(1, 0, 2)

    def pool(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(R, n, P) genomes, (R, n) fitness and (R, n) team G of the members, for the
        selection pool."""
        return self.table(), self.fitness.T, np.broadcast_to(self.team_G, self.fitness.T.shape)

    def select(
        self,
        elite_G: np.ndarray,
        population: np.ndarray,
        team_index: np.ndarray,
        team_G: np.ndarray,
        fitness: np.ndarray,
    ) -> None:
        """Keep the n best of this generation's teams by G, in place.

        Args:
            elite_G: (n,) G of the elite teams' episodes.
            population: (R, k, P) the genomes the training teams played (before evolution).
            team_index: (M, R) the policy of each rover in each training team.
            team_G: (M,) G of the training teams.
            fitness: (R, k) the fitness the generation assigned.
        """
        n, n_pop = self.n, population.shape[0]
        G = np.concatenate([elite_G, team_G])
        best = np.argsort(-G, kind="stable")[:n]
        from_elite = best < n
        team = team_index[np.where(from_elite, 0, best - n)]  # (n, R); rows of elites unused
        rovers = np.arange(n_pop)[None, :]
        elite = np.minimum(best, n - 1)  # rows of training teams unused
        genomes = np.where(from_elite[:, None, None], self.genomes[elite], population[rovers, team])
        member_fitness = np.where(from_elite[:, None], self.fitness[elite], fitness[rovers, team])
        self.team_G = np.where(from_elite, self.team_G[elite], team_G[np.maximum(best - n, 0)])
        self.genomes, self.fitness = genomes, member_fitness

    def state(self) -> dict[str, np.ndarray]:
        return {"team_elites": self.genomes, "team_elite_fitness": self.fitness,
                "team_elite_G": self.team_G}  # fmt: skip

    def load(self, arrays: dict[str, np.ndarray]) -> None:
        self.genomes = np.array(arrays["team_elites"])
        self.fitness = np.array(arrays["team_elite_fitness"])
        self.team_G = np.array(arrays.get("team_elite_G", np.full(self.n, np.nan)))  # 0.6
