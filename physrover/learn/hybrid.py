"""MERL's hybrid: a gradient learner whose actors migrate into the CCEA's populations.

Majumdar, Khadka et al. 2020, "Evolutionary Reinforcement Learning for Sample-Efficient
Multiagent Coordination" (ICML; code ShawK91/MERL, read in
``experiments/notes/merl-algorithm.md``). Configured by ``[hybrid]``
(:class:`~physrover.config.hybrid.HybridConfig`). In a migration generation (every
``period``-th, counted from 1), after selection and mutation:

1. the learner (physrover's MAPPO, a registered trainer) plays ``iterations`` iterations
   of ``episodes`` episodes on its own env and start states and updates on its own dense
   signal (``reward``: MERL's proximity reward by default, never G);
2. its deterministic actor, exported as one CCEA genome per rover
   (``Trainer.policy_genomes()``: the policy's mean, ``tanh(W2 relu(W1 o + b1) + b2)``, the
   CCEA's network), replaces one slot of each rover's population, drawn uniformly at random
   among the slots selection did not keep (MERL's "unselects", not the worst): the binary
   tournament's losers, or the offspring slots under ``selection = "elites"``;
3. each migrant is mutated like the offspring (``mutate``; MERL mutates it too) and carries
   no fitness (NaN) until it plays.

The migrant then plays in the next generation's random teams and competes on the run's
fitness like any offspring; with ``together`` the rovers' migrants form one team of that
generation's first round (:meth:`Hybrid.team_up`), as MERL's whole-team migrant always
plays. Nothing flows back: the learner never sees the populations.

Departures from MERL, stated: MERL's learners are off-policy TD3 fed by the evolutionary
episodes too; MAPPO is on-policy, so the learner learns from its own episodes only. MERL's
default evolves whole teams (one multi-head network); physrover keeps the paper's per-rover
populations (MERL's ``-ps none``) and MAPPO shares one actor among the rovers, so every
rover receives the same migrant. MERL migrates its actor as synced before the generation's
updates; here the actor after them.

Random streams: the learner's own (from the run's seed), and one generator for the slot
draws and the migrants' mutation, so the CCEA's streams are those of a run without the
hybrid.
"""

from __future__ import annotations

import math

import numpy as np

from physrover.config import RunConfig
from physrover.core.registry import TRAINERS
from physrover.learn.evolution import mutate


class Hybrid:
    """The learner and its migrations (see the module docstring).

    ``Hybrid(config, seed)``: ``seed`` a SeedSequence, from which the learner's seed and the
    migration generator are spawned. ``migrate(generation, genomes, carried, losers)``
    after every generation's evolution; ``state()`` / ``load()`` for checkpoints.
    """

    def __init__(self, config: RunConfig, seed: np.random.SeedSequence):
        self.config, hybrid = config, config.hybrid
        learner_seed, migration_seed = seed.spawn(2)
        spec = TRAINERS[hybrid.learner]
        learner_config = spec.config(
            num_envs=hybrid.episodes, total_episodes=hybrid.episodes, hidden=config.learn.hidden,
            reward=hybrid.reward, seed=int(learner_seed.generate_state(1)[0] >> 1),
            eval_episodes=1, lr=hybrid.lr, centralised_critic=hybrid.centralised_critic,
        )  # fmt: skip
        self.learner = spec.load()(learner_config, config.domain)
        self.rng = np.random.default_rng(migration_seed)
        self.learner_G = math.nan
        """Mean G of the learner's training episodes in the latest migration generation
        (its stochastic policy; NaN before the first)."""
        self.slots: np.ndarray | None = None
        """(R,) the slot each rover's migrant went into, in the latest migration."""

    def team_up(self, order: np.ndarray, completed: int) -> None:
        """With ``together``, in the generation after a migration (``completed``, the
        generations run so far, migrated): swap, in each rover's row of round 0 of the team
        plan ``order`` (rounds, R, k; in place), its migrant into team 0, so the migrants
        play as one team. The other teams keep their random members (one swap per rover;
        no random draw)."""
        if not (self.config.hybrid.together and completed > 0 and self.due(completed)):
            return
        rows = np.arange(order.shape[1])
        team = np.argmax(order[0] == self.slots[:, None], axis=1)  # the migrant's team
        order[0, rows, team], order[0, rows, 0] = order[0, rows, 0], self.slots

    def due(self, generation: int) -> bool:
        """Whether generation ``generation`` (counted from 1) migrates."""
        return generation % self.config.hybrid.period == 0

    def open_slots(self, losers: np.ndarray | None, n_rovers: int) -> np.ndarray:
        """(R, n) the slots of each population that selection did not keep: the binary
        tournament's ``losers`` (R, k // 2), or under ``selection = "elites"`` (``losers``
        None) the offspring's, after the elites."""
        if losers is not None:
            return losers
        learn = self.config.learn
        first = learn.n_individual_elites + learn.n_team_fitness_elites
        offspring = np.arange(first, learn.population)
        return np.broadcast_to(offspring, (n_rovers, len(offspring)))

    def migrate(self, generation: int, genomes: np.ndarray, carried: np.ndarray,
                losers: np.ndarray | None) -> float:  # fmt: skip
        """In a migration generation (else nothing), train the learner and write its actor
        into a random one of :meth:`open_slots` of each rover r's population ``genomes``
        (R, k, P), in place; in ``carried`` (R, k) the migrants' fitness becomes NaN.
        Returns :attr:`learner_G` of this generation (NaN if it did not migrate)."""
        if not self.due(generation):
            return math.nan
        hybrid, learn = self.config.hybrid, self.config.learn
        open_slots = self.open_slots(losers, genomes.shape[0])
        G = [self.learner.iteration(evaluate=False)["train_G_mean"]
             for _ in range(hybrid.iterations)]  # fmt: skip
        self.learner_G = float(np.mean(G))
        migrants = self.learner.policy_genomes().astype(genomes.dtype)  # (R, P)
        if hybrid.mutate:
            mutate(migrants, self.rng, learn.mutation_rate, learn.mutation_scale, learn.mutation)
        rows = np.arange(genomes.shape[0])
        self.slots = open_slots[rows, self.rng.integers(open_slots.shape[1], size=len(rows))]
        genomes[rows, self.slots] = migrants
        carried[rows, self.slots] = np.nan
        return self.learner_G

    def state(self) -> tuple[dict[str, np.ndarray], dict]:
        """(arrays, meta) to continue bit-identically: the learner's and the generator's."""
        arrays, meta = self.learner.state()
        learner_G = None if math.isnan(self.learner_G) else self.learner_G  # JSON has no NaN
        slots = None if self.slots is None else self.slots.tolist()
        return arrays, {"learner": meta, "rng": self.rng.bit_generator.state,
                        "learner_G": learner_G, "slots": slots}  # fmt: skip

    def load(self, arrays: dict[str, np.ndarray], meta: dict) -> None:
        self.learner.load_state(arrays, meta["learner"])
        self.rng.bit_generator.state = meta["rng"]
        self.learner_G = math.nan if meta["learner_G"] is None else float(meta["learner_G"])
        slots = meta.get("slots")  # absent from checkpoints of physrover before 'together'
        self.slots = None if slots is None else np.array(slots, dtype=np.int64)
