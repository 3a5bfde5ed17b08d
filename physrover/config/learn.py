"""The learner's configuration: ``[learn]``, the CCEA and its fitness methods."""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from physrover.config.base import ConfigBase, check, check_choice
from physrover.core.registry import CREDITS, FITNESS_METHODS, TRAINERS

OPTIMIZERS = ("sgd", "adam")


@dataclasses.dataclass(frozen=True)
class LearnConfig(ConfigBase):
    """The CCEA and the fitness methods (paper Sections 2.1, 3, 4.2; defaults are the paper's).

    Methods: ``D`` and ``G`` use one episode's feedback as fitness; ``average`` the mean and
    ``leniency`` the max of the feedback over ``n_samples`` episodes with fresh random
    teammates; ``hall-of-fame`` the feedback with the best team found so far as teammates;
    ``mean-critic`` (Eq. 4, regular updates Eqs. 6-8), ``max-critic`` (Eq. 3, inexact
    updates Eqs. 9-10) and the two other combinations ``max-critic-regular`` and
    ``mean-critic-inexact`` use a fitness critic.
    """

    section: ClassVar[str] = "learn"

    method: str = "max-critic"
    """Fitness method (see the class docstring)."""
    feedback: str = "D"
    """The credit signal, each rover's immediate feedback: "D" (difference evaluation, Eq. 1),
    "G", or any registered in :data:`physrover.core.registry.CREDITS`
    (physrover.domain.scoring.credit)."""
    generations: int = 5000
    """Generations to run."""
    seed: int = 0
    """Seeds every random draw of the run (world, initial policies, evolution, critics)."""
    population: int = 50
    """Policies per rover, k."""
    hidden: int = 32
    """Hidden units of each policy (8 -> hidden -> 2, ReLU then tanh)."""
    mutation_rate: float = 0.01
    """Probability that an offspring's weight is mutated."""
    mutation_scale: float = 1.0
    """Scale of the noise added to a mutated weight (the Cauchy's scale, the Gaussian's std)."""
    mutation: str = "cauchy"
    """The mutation noise: "cauchy" (the paper's) or "gauss" (the lab's later code, with
    ``mutation_rate = 0.5`` and ``mutation_scale = 0.1``)."""
    team_formation: str = "random"
    """How each round's teams are formed: "random" (a fresh permutation of every population,
    the paper's) or "softmax" (the lab's later code: teams drawn in turn, each member by a
    softmax over its population's fitness at ``softmax_temperature`` among those not yet
    drawn, so good policies tend to play together; :mod:`physrover.learn.teams`)."""
    softmax_temperature: float = 1.0
    """Temperature of softmax team formation (the lab's is 1, in fitness units)."""
    selection: str = "tournament"
    """"tournament" (binary tournament, losers replaced by mutated winners: the paper's) or
    "elites" (the lab's n-elites tournament: ``n_individual_elites`` best policies kept
    unmutated, the rest mutated winners of binary tournaments, with ``n_team_elites`` best
    teams replayed; :mod:`physrover.learn.evolution`, :mod:`physrover.learn.team_elites`)."""
    n_individual_elites: int = 10
    """Under ``selection = "elites"``: policies per population copied unmutated (the best
    by fitness, the champion first)."""
    n_team_elites: int = 10
    """Under ``selection = "elites"``: best teams by G kept whole and replayed each
    generation; their members join the selection pool (0: none)."""
    n_samples: int = 10
    """Episodes per generation for the average and leniency methods."""
    eval_episodes: int = 10
    """Fresh episodes of the champion team per generation (the learning curve)."""
    critic_hidden: int = 80
    """Hidden units of the intermediate critic (10 -> hidden -> 1, leaky ReLU)."""
    critic_step_input: bool = False
    """Beyond the paper: the critic also sees the pair's step t / (T - 1) as an input (11
    inputs with the paper's sensor); off is the paper's critic."""
    critic_top_k: int = 1
    """Beyond the paper: the max critic's fitness is the mean of the k largest critic values
    along the trajectory (1: their max, Eq. 3, the paper's). Inexact updates only."""
    critic_ensemble: int = 1
    """Beyond the paper: each rover's intermediate critic is an ensemble of this many
    critics (own random initialisations, own mini-batches from the rover's replay); a pair's
    value is their mean plus ``critic_optimism`` times their standard deviation (1: the
    paper's single critic)."""
    critic_optimism: float = 0.0
    """Beyond the paper: the weight beta of the ensemble's spread in a pair's value,
    ``mean + beta * std`` (optimism under the critic's uncertainty; needs an ensemble)."""
    critic_output_weights: str = "fixed"
    """The critic's hidden-to-output weights: "fixed" to 1 (the paper's) or "trained" with
    the other parameters (an ablation; initialised to 1)."""
    critic_target: str = "episode"
    """What each state-action pair of the critic's replay is fitted to: "episode" (the
    paper's: its trajectory's immediate feedback, Eqs. 9-10) or, beyond the paper, "step"
    (the feedback signal of the step its action leads to, taken alone:
    :func:`physrover.domain.scoring.difference.step_credits`; feedback D, G or D++, inexact
    updates, POIs without rules)."""
    leaky_slope: float = 0.01
    """Slope of the critic's leaky ReLU for negative inputs."""
    critic_lr: float = 5e-6
    """Critic learning rate alpha_w (Eqs. 7, 9); 0 freezes the critic at its random
    initialisation (an ablation: is it the training or the random shape that helps?)."""
    critic_optimizer: str = "sgd"
    """"sgd": plain mini-batch gradient steps of Eq. 7/9; "adam": Adam on the same gradient."""
    replay_trajectories: int = 500
    """Replay capacity, trajectories, for regular updates."""
    trajectory_batch: int = 7
    """Trajectories per mini-batch, regular updates."""
    trajectory_batches: int = 7
    """Mini-batches per generation, regular updates."""
    replay_pairs: int = 25000
    """Replay capacity, state-action pairs, for inexact updates."""
    pair_batch: int = 50
    """State-action pairs per mini-batch, inexact updates."""
    pair_batches: int = 50
    """Mini-batches per generation, inexact updates."""
    trajectory_loss: str = "mse"
    """Beyond the paper, trajectory critics (``gru-critic``, ``gru-sum-critic``,
    ``recurrent-max-critic``, ``attention-critic``): "mse" (the value) or "rank" (a
    logistic loss on the order of each pair of trajectories in a mini-batch;
    :mod:`physrover.learn.trajectory_critics`). They draw ``trajectory_batches``
    mini-batches of ``trajectory_batch`` trajectories from the last ``replay_trajectories``;
    ``recurrent-max-critic``'s per-pair critic has ``critic_hidden`` units of slope
    ``leaky_slope`` and learns at ``critic_lr`` with ``critic_optimizer``, as the paper's."""
    trajectory_hidden: int = 32
    """Hidden size of a trajectory critic (the GRU's state, the attention's embedding)."""
    trajectory_lr: float = 1e-3
    """Adam's learning rate for a trajectory critic."""
    curriculum_start: int = 0
    """Beyond the paper: a coupling curriculum (:mod:`physrover.learn.curriculum`). 0: off,
    every episode at the domain's n_req (the paper's); c >= 1: the training episodes are
    played at coupling c (each POI's ``min(c, n_req)``), which goes up by one each time the
    champion team scores ``curriculum_threshold`` of the POIs' total value
    ``curriculum_patience`` generations in a row. The learning curve is always at the
    domain's coupling."""
    curriculum_threshold: float = 0.5
    """The fraction of the POIs' total value (sum of V_k) the champion's mean G at the
    training coupling must reach for the coupling to tighten."""
    curriculum_patience: int = 10
    """Generations in a row the champion must reach ``curriculum_threshold``."""
    checkpoint_every: int = 100
    """Write a checkpoint every this many generations (and at the end)."""

    def _has_critic(self) -> bool:
        """Whether the fitness method has a fitness critic (its registry entry says)."""
        return bool(getattr(FITNESS_METHODS[self.method], "critic", False))

    def __post_init__(self) -> None:
        self._coerce_fields()
        if self.method not in TRAINERS:
            check(
                self.method in FITNESS_METHODS,
                "method",
                FITNESS_METHODS.unknown_message(
                    self.method, f", or a trainer: {', '.join(TRAINERS)}"
                ),
            )
        check(self.feedback in CREDITS, "feedback", CREDITS.unknown_message(self.feedback))
        check_choice(self.critic_optimizer, OPTIMIZERS, "critic_optimizer")
        check_choice(self.critic_output_weights, ("fixed", "trained"), "critic_output_weights")
        check_choice(self.critic_target, ("episode", "step"), "critic_target")
        check(self.critic_top_k >= 1, "critic_top_k", f"must be >= 1, got {self.critic_top_k}")
        check(
            self.critic_top_k == 1 or self.method in ("max-critic", *TRAINERS),
            "critic_top_k",
            f"a softer max is for the max critic with inexact updates, not {self.method!r}",
        )
        for name, paper in (("critic_ensemble", 1), ("critic_optimism", 0.0),
                            ("critic_output_weights", "fixed"),
                            ("critic_step_input", False),
                            ("critic_target", "episode")):  # fmt: skip
            check(
                getattr(self, name) == paper or self.method in TRAINERS or self._has_critic(),
                name,
                f"changes the fitness critic, which {self.method!r} does not have",
            )
        check_choice(self.trajectory_loss, ("mse", "rank"), "trajectory_loss")
        spec = FITNESS_METHODS[self.method] if self.method in FITNESS_METHODS else None
        check(
            self.critic_target == "episode"
            or getattr(spec, "pair_replay", False)
            or self.method in TRAINERS,
            "critic_target",
            f"per-step targets need a critic that replays pairs (inexact updates: max-critic, "
            f"mean-critic-inexact), not {self.method!r}",
        )
        trajectory = bool(getattr(spec, "trajectory", False))
        for name, default in (("trajectory_loss", "mse"), ("trajectory_hidden", 32),
                              ("trajectory_lr", 1e-3)):  # fmt: skip
            check(
                getattr(self, name) == default or trajectory or self.method in TRAINERS,
                name,
                f"configures a trajectory critic, which {self.method!r} does not have",
            )
        if self.method == "recurrent-max-critic":  # the paper's update: critic_lr, every step
            for name, default in (("trajectory_loss", "mse"), ("trajectory_lr", 1e-3)):
                check(getattr(self, name) == default, name,
                      "recurrent-max-critic learns as the paper's critic (critic_lr and "
                      "critic_optimizer, every step's value on the squared error)")  # fmt: skip
        check(
            self.trajectory_lr > 0 and math.isfinite(self.trajectory_lr),
            "trajectory_lr",
            f"must be > 0, got {self.trajectory_lr}",
        )
        check(
            self.critic_optimism >= 0 and math.isfinite(self.critic_optimism),
            "critic_optimism",
            f"must be >= 0, got {self.critic_optimism}",
        )
        check(
            self.critic_optimism == 0 or self.critic_ensemble > 1,
            "critic_optimism",
            "an ensemble's spread needs critic_ensemble > 1",
        )
        check(self.generations >= 1, "generations", f"must be >= 1, got {self.generations}")
        check(self.seed >= 0, "seed", f"must be >= 0, got {self.seed}")
        check(self.population >= 2, "population", f"must be >= 2, got {self.population}")
        self.check_at_least(
            1, "hidden", "n_samples", "eval_episodes", "critic_hidden", "critic_ensemble",
            "trajectory_hidden",
            "replay_trajectories",
            "trajectory_batch", "trajectory_batches", "replay_pairs", "pair_batch",
            "pair_batches", "checkpoint_every",
        )  # fmt: skip
        check(
            0.0 <= self.mutation_rate <= 1.0,
            "mutation_rate",
            f"must be in [0, 1], got {self.mutation_rate}",
        )
        check(
            self.mutation_scale > 0 and math.isfinite(self.mutation_scale),
            "mutation_scale",
            f"must be > 0, got {self.mutation_scale}",
        )
        self._check_ccea_options()
        self._check_curriculum()
        check(
            self.critic_lr >= 0 and math.isfinite(self.critic_lr),
            "critic_lr",
            f"must be >= 0 (0 freezes the critic at its random start), got {self.critic_lr}",
        )
        check(
            0.0 <= self.leaky_slope < 1.0,
            "leaky_slope",
            f"must be in [0, 1), got {self.leaky_slope}",
        )

    def _check_curriculum(self) -> None:
        """The coupling curriculum's options (those needing the domain: RunConfig's)."""
        check(self.curriculum_start >= 0, "curriculum_start",
              f"must be >= 0 (0: off), got {self.curriculum_start}")  # fmt: skip
        check(self.curriculum_start == 0 or self.method not in TRAINERS, "curriculum_start",
              f"is the CCEA's; {self.method!r} is a gradient-based trainer")  # fmt: skip
        check(
            0.0 < self.curriculum_threshold <= 1.0,
            "curriculum_threshold",
            f"must be in (0, 1], a fraction of the POIs' total value, got "
            f"{self.curriculum_threshold}",
        )
        check(self.curriculum_patience >= 1, "curriculum_patience",
              f"must be >= 1, got {self.curriculum_patience}")  # fmt: skip
        if self.curriculum_start == 0:
            for name, default in (("curriculum_threshold", 0.5), ("curriculum_patience", 10)):
                check(getattr(self, name) == default, name,
                      "configures the coupling curriculum: set curriculum_start")  # fmt: skip

    def _check_ccea_options(self) -> None:
        """The CCEA's team formation, selection and mutation options."""
        check_choice(self.mutation, ("cauchy", "gauss"), "mutation")
        check_choice(self.team_formation, ("random", "softmax"), "team_formation")
        check_choice(self.selection, ("tournament", "elites"), "selection")
        check(
            self.softmax_temperature > 0 and math.isfinite(self.softmax_temperature),
            "softmax_temperature",
            f"must be > 0, got {self.softmax_temperature}",
        )
        check(
            self.softmax_temperature == 1.0 or self.team_formation == "softmax",
            "softmax_temperature",
            'configures team_formation = "softmax"',
        )
        spec = FITNESS_METHODS[self.method] if self.method in FITNESS_METHODS else None
        check(
            self.team_formation == "random" or not getattr(spec, "plans_teams", False),
            "team_formation",
            f"{self.method!r} plans its own teams; softmax needs a method with random teams",
        )
        if self.selection != "elites":
            for name in ("n_individual_elites", "n_team_elites"):
                check(getattr(self, name) == 10, name, 'configures selection = "elites"')
            return
        check(
            1 <= self.n_individual_elites < self.population,
            "n_individual_elites",
            f'must be in [1, population) = [1, {self.population}) under selection = "elites" '
            f"(the champion is elite 0), got {self.n_individual_elites}",
        )
        check(self.n_team_elites >= 0, "n_team_elites", f"must be >= 0, got {self.n_team_elites}")
