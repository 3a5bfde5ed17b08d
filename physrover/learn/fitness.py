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

Every method is registered by name in :data:`physrover.core.registry.FITNESS_METHODS` (with a
one-line summary and the paper section, listed by ``physrover methods``); a new method is a
:class:`FitnessMethod` subclass plus one :func:`register_method` call, naming the class of
its settings if it has any (:mod:`physrover.learn.configs`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from physrover.config import (
    RESERVED_SECTIONS,
    ConfigBase,
    RunConfig,
    method_spec,
    settings_tables,
)
from physrover.core.registry import FITNESS_METHODS
from physrover.learn.configs import CriticConfig, SampledConfig, TrajectoryCriticConfig
from physrover.learn.critics import CriticSettings, FitnessCritic


class FitnessMethod:
    """How the CCEA turns a generation's episodes into each policy's fitness (the seam).

    The CCEA (:class:`physrover.learn.ccea.CCEA`) calls, once per generation and in this
    order:

    1. :meth:`plan`: which policy of each rover plays in which team, for each of the
       method's ``rounds``. Every round's k teams run as one batch of episodes, with the
       champion team's evaluation episodes appended.
    2. :meth:`assign`: the fitness of every policy from its episodes' feedback (the credit
       signal, D or G per the config) and team scores, and for methods with
       ``needs_trajectories`` its (s, a) trajectory of round 0.
    3. :meth:`observe_champion`: the team the generation evaluated and its score.
    4. evolution (selection and mutation) on the fitness, then :meth:`update`.

    Everything a method keeps between generations must come back from :meth:`state` and go
    in through :meth:`load` (arrays and JSON-able values; nested dicts and lists are fine):
    a resumed run is bit-identical to an uninterrupted one only if nothing is left out.

    Extra genomes: a team index in :meth:`plan` of k or more addresses
    ``extra_genomes()[r, index - k]``, genomes that are not in the population (the hall of
    fame's best team); the fitness of those is never asked for.
    """

    rounds = 1
    """Batches of k episodes (training rounds) per generation; each policy plays once per round."""
    needs_trajectories = False
    """Whether :meth:`assign` receives the policies' trajectories (the critics do)."""
    needs_step_feedback = False
    """Whether :meth:`assign` also receives ``step_feedback`` (``critic_target = "step"``)."""

    def plan(self, rng: np.random.Generator, n_rovers: int, k: int) -> np.ndarray:
        """(rounds, R, k) ints: ``order[q, r, m]`` is the policy of rover r in team m of
        round q. Default: a fresh random permutation of each population per round, so every
        policy plays exactly once per round with random teammates. Indices >= k address
        :meth:`extra_genomes`."""
        return np.argsort(rng.random((self.rounds, n_rovers, k)), axis=-1)

    def extra_genomes(self) -> np.ndarray | None:
        """(R, n, P) genomes that :meth:`plan` addresses as policies k, ..., k + n - 1, or
        None when the method uses none."""
        return None

    def observe_champion(self, genomes: np.ndarray, eval_G: float) -> None:
        """The champion team's (R, P) genomes and its evaluation G in this generation."""

    def assign(self, feedback: np.ndarray, G: np.ndarray, trajectories=None) -> np.ndarray:
        """Fitness (R, k), higher is better, NaN never selected.

        Args:
            feedback: (rounds, R, k) the credit of each policy's episode in each round.
            G: (rounds, R, k) the team score of each policy's episode.
            trajectories: (R, k, T, D) (s, a) pairs of each policy in round 0, D = the
                sensor's size + 2; None unless ``needs_trajectories``. The CCEA writes
                every generation's pairs into the same array: copy what is kept.

        With ``needs_step_feedback``, also ``step_feedback`` (R, k, T): each policy's credit
        at step t + 1 of round 0 alone (``Credit.per_step``), the step pair t leads to.
        """
        raise NotImplementedError

    def update(self, rng: np.random.Generator) -> float:
        """End-of-generation learning (after evolution, as Algorithm 1); returns a loss for
        metrics.csv's ``critic_loss``, or NaN when there is none. ``rng``: the run's critic
        generator."""
        return float("nan")

    def state(self) -> dict:
        """Everything kept between generations, for checkpoints (see the class docstring)."""
        return {}

    def load(self, state: dict) -> None:
        """Restore what :meth:`state` returned."""


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
        self.needs_step_feedback = getattr(critic.settings, "target", "episode") == "step"

    def assign(self, feedback, G, trajectories=None, step_feedback=None):
        fitness = self.critic.fitness(trajectories)  # with the critic before this update
        self.critic.store(trajectories, step_feedback if self.needs_step_feedback else feedback[0])
        return fitness

    def update(self, rng):
        return self.critic.update(rng)

    def state(self):
        return self.critic.state()

    def load(self, state):
        self.critic.load(state)


@dataclass(frozen=True)
class Problem:
    """What a fitness method is built for: the team and the sizes of its trajectories."""

    n_rovers: int
    steps: int
    """Steps of an episode, T."""
    obs_dim: int
    """Observations per rover (the sensor's size; 8 for the paper's)."""
    action_dim: int
    """Actions per rover (2)."""

    @property
    def pair_dim(self) -> int:
        """Inputs of a state-action pair, the critics' input size."""
        return self.obs_dim + self.action_dim


@dataclass(frozen=True)
class MethodSpec:
    """A registered fitness method: how to build it, its settings, and what to tell a user.

    ``build(settings, problem, rng)`` returns a :class:`FitnessMethod` for a
    :class:`Problem`; ``settings`` is the run's instance of ``config`` (None for a method
    without one); ``rng`` is the run's critic generator (initial critic weights), the only
    draw a method makes at construction.
    """

    build: Callable[[Any, Problem, np.random.Generator], FitnessMethod]
    summary: str
    """One line: what the fitness of a policy is."""
    section: str
    """Where the paper describes it."""
    config: type | None = None
    """Its settings: a frozen :class:`~physrover.config.ConfigBase` dataclass whose
    ``section`` names its TOML table (``[critic]``), shared by the methods that take the same
    settings; it may define ``check_run(run)`` for the rules across a run's tables (which of
    the methods it configures, the credit, the domain: a
    :class:`~physrover.config.RunConfig`). None: the method has no settings of its own."""
    plans_teams: bool = False
    """Whether its :meth:`FitnessMethod.plan` forms teams its own way (the hall of fame), so
    ``team_formation = "softmax"`` cannot replace it."""
    pair_replay: bool = False
    """Whether its critic replays pairs (inexact updates): ``critic_target = "step"``."""


def register_method(
    name: str,
    build,
    summary: str,
    section: str,
    config: type | None = None,
    plans_teams: bool = False,
    pair_replay: bool = False,
) -> MethodSpec:
    """Add a fitness method under ``name`` (usable in TOML, ``--method`` and ``--set``).

    ``build(settings, problem, rng)``: see :class:`MethodSpec`; ``config``: the class of its
    settings (its own or a built-in one, e.g. :class:`~physrover.learn.configs.CriticConfig`),
    whose table no trainer may also use; ``plans_teams``: its ``plan`` is not random teams;
    ``pair_replay``: see :class:`MethodSpec`.
    """
    if config is not None:
        if not (isinstance(config, type) and issubclass(config, ConfigBase) and config.section):
            raise TypeError(f"method {name!r}: config must be a ConfigBase dataclass with a "
                            f"section, got {config!r}")  # fmt: skip
        others = [getattr(method_spec(m), "config", None) for m in
                  settings_tables().get(config.section, []) if m != name]  # fmt: skip
        if config.section in RESERVED_SECTIONS or any(c is not config for c in others):
            raise ValueError(f"method {name!r}: [{config.section}] is another table's (the "
                             "domain's, [learn], a trainer's or another method's settings); "
                             "give its settings class its own section")  # fmt: skip
    spec = MethodSpec(build, summary, section, config, plans_teams, pair_replay)
    return FITNESS_METHODS.register(name, spec)


def _critic(aggregation: str, update: str):
    """Build the paper's critic of ``aggregation`` ("mean" | "max", Eqs. 3-4) and ``update``
    ("regular" Eqs. 6-8 | "inexact" Eqs. 9-10) from a :class:`CriticConfig`."""

    def build(cfg: CriticConfig, problem: Problem, rng: np.random.Generator):
        settings = CriticSettings.from_config(cfg, aggregation, update)
        return CriticFitness(
            FitnessCritic(problem.n_rovers, problem.steps, problem.pair_dim, settings, rng)
        )

    return build


def _trajectory_critic(model: str, readout: str):
    """Build a trajectory critic (:mod:`physrover.learn.trajectory_critics`) of ``model``
    read out by ``readout`` from a :class:`TrajectoryCriticConfig`."""

    def build(cfg: TrajectoryCriticConfig, problem: Problem, rng: np.random.Generator):
        from physrover.learn.trajectory_critics import TrajectoryCritic, TrajectorySettings

        settings = TrajectorySettings.from_config(cfg, model, readout)
        return CriticFitness(TrajectoryCritic(problem.n_rovers, problem.steps,
                                              problem.pair_dim, settings, rng))  # fmt: skip

    return build


register_method(
    "D",
    lambda settings, problem, rng: SingleEpisode(use_G=False),
    "the policy's difference evaluation D (Eq. 1) in one episode",
    "Sec. 2.2 (Eq. 1)",
)
register_method(
    "G",
    lambda settings, problem, rng: SingleEpisode(use_G=True),
    "the team's score G of the policy's one episode",
    "Sec. 4.1 (Eq. 11)",
)
register_method(
    "average",
    lambda settings, problem, rng: Sampled(settings.n_samples, "mean"),
    "mean feedback over n_samples episodes with fresh teammates",
    "Sec. 2.3, 4",
    config=SampledConfig,
)
register_method(
    "leniency",
    lambda settings, problem, rng: Sampled(settings.n_samples, "max"),
    "max feedback over n_samples episodes with fresh teammates",
    "Sec. 2.3",
    config=SampledConfig,
)
register_method(
    "hall-of-fame",
    lambda settings, problem, rng: HallOfFame(problem.n_rovers),
    "feedback with the best team found so far as teammates",
    "Sec. 2.3",
    plans_teams=True,
)
register_method(
    "mean-critic",
    _critic("mean", "regular"),
    "fitness critic, mean over the trajectory, regular updates",
    "Sec. 3.1-3.2 (Eqs. 4, 6-8)",
    config=CriticConfig,
)
register_method(
    "max-critic",
    _critic("max", "inexact"),
    "fitness critic, max over the trajectory, inexact updates (the paper's best)",
    "Sec. 3.1, 3.3 (Eqs. 3, 6, 9-10)",
    config=CriticConfig,
    pair_replay=True,
)
register_method(
    "max-critic-regular",
    _critic("max", "regular"),
    "fitness critic, max over the trajectory, regular updates",
    "Sec. 3.1-3.2 (Eqs. 3, 6-8)",
    config=CriticConfig,
)
register_method(
    "mean-critic-inexact",
    _critic("mean", "inexact"),
    "fitness critic, mean over the trajectory, inexact updates",
    "Sec. 3.1, 3.3 (Eqs. 4, 6, 9-10)",
    config=CriticConfig,
    pair_replay=True,
)


register_method(
    "gru-critic",
    _trajectory_critic("gru", "final"),
    "trajectory critic: a GRU over the whole episode, read out at its end",
    "beyond the paper (trajectory critics)",
    config=TrajectoryCriticConfig,
)
register_method(
    "gru-sum-critic",
    _trajectory_critic("gru", "sum"),
    "trajectory critic: a GRU over the whole episode, the sum of its per-step values",
    "beyond the paper (trajectory critics)",
    config=TrajectoryCriticConfig,
)
register_method(
    "recurrent-max-critic",
    _trajectory_critic("recurrent-max", "max"),
    "trajectory critic: the max critic whose pairs also see a GRU's summary of the steps "
    "before them",
    "beyond the paper (trajectory critics)",
    config=TrajectoryCriticConfig,
)
register_method(
    "attention-critic",
    _trajectory_critic("attention", "final"),
    "trajectory critic: self-attention over the episode's steps, mean-pooled",
    "beyond the paper (trajectory critics)",
    config=TrajectoryCriticConfig,
)


def make_method(config: RunConfig, problem: Problem, rng: np.random.Generator) -> FitnessMethod:
    """The fitness method ``config.learn.method`` with its settings (``config.settings``);
    ``rng`` initialises critics."""
    return FITNESS_METHODS[config.learn.method].build(config.settings, problem, rng)
