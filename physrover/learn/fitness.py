"""Fitness methods: how the CCEA turns a generation's episodes into each policy's fitness.

Every method sees the same thing, per training round q (each policy plays exactly once per
round, in a team of randomly drawn teammates): the immediate feedback of each policy's
episode (D or G, per the config) and, for the critics, its trajectory of (s, a) pairs.
Hooks: ``rounds`` (training rounds per generation), ``assign`` (fitness from this
generation's episodes, Algorithm 1's inner loop) and ``update`` (end of generation).

- ``D`` / ``G``: the feedback (or the team score G) of the one episode;
- ``average`` / ``leniency``: mean / max of the feedback over ``n_samples`` rounds
  (paper Section 2.3 and the "average of 10 episodes" baseline of Section 4);
- ``hall-of-fame``: the feedback of an episode in which the policy plays with the hall of
  fame, the best team found so far (the champion team with the highest evaluation G), as
  teammates (paper Section 2.3, "optimizing the best team"): R x k episodes a generation;
- critics: the fitness critic's aggregate over the trajectory (Eqs. 3-4), with the feedback
  stored in the replay buffer and the critic updated after evolution (Algorithm 1).
"""

from __future__ import annotations

import numpy as np

from physrover.config import LearnConfig
from physrover.learn.critics import CriticSettings, FitnessCritic


class FitnessMethod:
    rounds = 1
    needs_trajectories = False

    def plan(self, rng: np.random.Generator, n_rovers: int, k: int) -> np.ndarray:
        """(rounds, R, k) policy of rover r in team m of round q: fresh random permutations."""
        return np.argsort(rng.random((self.rounds, n_rovers, k)), axis=-1)

    def extra_genomes(self) -> np.ndarray | None:
        """(R, n, P) genomes that ``plan`` addresses as policies k, k + 1, ... (or None)."""
        return None

    def observe_champion(self, genomes: np.ndarray, eval_G: float) -> None:
        """The champion team's (R, P) genomes and its evaluation G in this generation."""

    def assign(self, feedback: np.ndarray, G: np.ndarray, trajectories=None) -> np.ndarray:
        """Fitness (R, k) from (rounds, R, k) feedback and team scores of each policy's
        episodes and, for critics, (R, k, T, 10) trajectories of round 0."""
        raise NotImplementedError

    def update(self, rng: np.random.Generator) -> float:
        """End-of-generation learning; returns a loss, or NaN when there is none."""
        return float("nan")

    def state(self) -> dict:
        return {}

    def load(self, state: dict) -> None:
        pass


class SingleEpisode(FitnessMethod):
    def __init__(self, use_G: bool):
        self.use_G = use_G

    def assign(self, feedback, G, trajectories=None):
        return (G if self.use_G else feedback)[0]


class Sampled(FitnessMethod):
    def __init__(self, rounds: int, how: str):
        self.rounds, self.how = rounds, how

    def assign(self, feedback, G, trajectories=None):
        return feedback.mean(0) if self.how == "mean" else feedback.max(0)


class HallOfFame(FitnessMethod):
    """Each policy plays with the hall-of-fame team as teammates; round q tests rover q."""

    def __init__(self, n_rovers: int):
        self.rounds = n_rovers
        self.genomes: np.ndarray | None = None  # (R, P) best team so far
        self.score = -np.inf

    def plan(self, rng, n_rovers, k):
        order = np.full((n_rovers, n_rovers, k), k)  # everyone plays the hall-of-fame genome ...
        order[np.arange(n_rovers), np.arange(n_rovers)] = np.arange(k)  # ... but rover q
        return order

    def extra_genomes(self):
        return None if self.genomes is None else self.genomes[:, None, :]

    def observe_champion(self, genomes, eval_G):
        if self.genomes is None or eval_G > self.score:
            self.genomes, self.score = genomes.copy(), eval_G

    def assign(self, feedback, G, trajectories=None):
        rovers = np.arange(feedback.shape[1])
        return feedback[rovers, rovers]  # rover r's policies were tested in round r

    def state(self):
        return {"genomes": self.genomes, "score": float(self.score)}

    def load(self, state):
        self.genomes = np.array(state["genomes"], dtype=np.float32)
        self.score = float(state["score"])


class CriticFitness(FitnessMethod):
    needs_trajectories = True

    def __init__(self, critic: FitnessCritic):
        self.critic = critic

    def assign(self, feedback, G, trajectories=None):
        fitness = self.critic.fitness(trajectories)  # with the critic before this update
        self.critic.store(trajectories, feedback[0])
        return fitness

    def update(self, rng):
        return self.critic.update(rng)

    def state(self):
        return self.critic.state()

    def load(self, state):
        self.critic.load(state)


CRITICS = {
    "mean-critic": ("mean", "regular"),
    "max-critic": ("max", "inexact"),
    "max-critic-regular": ("max", "regular"),
    "mean-critic-inexact": ("mean", "inexact"),
}


def make_method(
    cfg: LearnConfig, n_rovers: int, steps: int, rng: np.random.Generator
) -> FitnessMethod:
    """The fitness method named by ``cfg.method``; ``rng`` initialises critics."""
    if cfg.method in ("D", "G"):
        return SingleEpisode(use_G=cfg.method == "G")
    if cfg.method == "hall-of-fame":
        return HallOfFame(n_rovers)
    if cfg.method in ("average", "leniency"):
        return Sampled(cfg.n_samples, "mean" if cfg.method == "average" else "max")
    aggregation, update = CRITICS[cfg.method]
    regular = update == "regular"
    settings = CriticSettings(
        aggregation=aggregation,
        update=update,
        hidden=cfg.critic_hidden,
        slope=cfg.leaky_slope,
        lr=cfg.critic_lr,
        optimizer=cfg.critic_optimizer,
        capacity=cfg.replay_trajectories if regular else cfg.replay_pairs,
        batch=cfg.trajectory_batch if regular else cfg.pair_batch,
        batches=cfg.trajectory_batches if regular else cfg.pair_batches,
    )
    return CriticFitness(FitnessCritic(n_rovers, steps, settings, rng))
