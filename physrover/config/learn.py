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
    """What every fitness method of the CCEA shares (paper Sections 2.1, 4.2; defaults are
    the paper's): the method's name, the credit signal, the population, mutation, selection,
    team formation, the evaluation and the coupling curriculum.

    Methods (``physrover methods`` lists them): ``D`` and ``G`` use one episode's feedback
    as fitness; ``average`` the mean and ``leniency`` the max of the feedback over
    ``n_samples`` episodes with fresh random teammates; ``hall-of-fame`` the feedback with
    the best team found so far as teammates; ``mean-critic`` (Eq. 4, regular updates Eqs.
    6-8), ``max-critic`` (Eq. 3, inexact updates Eqs. 9-10) and the two other combinations
    ``max-critic-regular`` and ``mean-critic-inexact`` use a fitness critic. A method's own
    settings are its table beside this one (``[sampled]``, ``[critic]``,
    ``[trajectory_critic]``: :mod:`physrover.learn.configs`; a trainer's ``[mappo]``...).
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
    activation: str = "relu"
    """The policies' hidden layer: "relu" (the paper's) or "tanh" (the lab's code's)."""
    weight_init: str = "fan-in"
    """The policies' initial weights and biases: "fan-in", uniform in +-1/sqrt(fan_in)
    (PyTorch's default), or "uniform", in +-1 (the lab's code's)."""
    mutation_rate: float = 0.01
    """Probability that an offspring's weight is mutated."""
    mutation_scale: float = 1.0
    """Scale of the noise added to a mutated weight (the Cauchy's scale, the Gaussian's std)."""
    mutation: str = "cauchy"
    """The mutation noise: "cauchy" (the paper's) or "gauss" (the lab's later code, with
    ``mutation_rate = 0.5`` and ``mutation_scale = 0.1``)."""
    team_formation: str = "random"
    """How each round's teams are formed: "random" (a fresh permutation of every population,
    the paper's), "softmax" (the lab's later code: teams drawn in turn, each member by a
    softmax over its population's fitness at ``softmax_temperature`` among those not yet
    drawn, so good policies tend to play together) or "rank" (the lab's ``fixed_teams``:
    each population sorted by fitness, the best of each in team 0, the second in team 1,
    ...; :mod:`physrover.learn.teams`)."""
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
    n_team_fitness_elites: int = 0
    """Under ``selection = "elites"``: policies per population also copied unmutated, the
    best by the G of the team each played in (the lab's
    ``n_individual_elites_based_on_team_fitness``), after the fitness elites."""
    n_team_elites: int = 10
    """Under ``selection = "elites"``: best teams by G kept whole and replayed each
    generation; their members join the selection pool (0: none)."""
    rollouts: int = 1
    """Episodes each team plays per generation, its G and every agent's feedback the mean
    over them (the lab's ``num_rollouts``); under the scenario's ``redraw = "generation"``
    every team plays the same ``rollouts`` start states (the lab's seeds, shared by all
    teams of a generation). Methods "D" and "G" only (:mod:`physrover.learn.rollouts`)."""
    eval_episodes: int = 10
    """Fresh episodes of the evaluated team per generation (the learning curve)."""
    eval_team: str = "champion"
    """The team the learning curve plays: "champion" (every population's best policy by
    fitness: the paper's, and the lab's ``test_adhoc_team_switch``) or "best-team" (the
    previous generation's team with the highest G, as it played: the lab's default test
    team; :mod:`physrover.learn.eval_team`)."""
    curriculum_start: int = 0
    """Beyond the paper: a coupling curriculum (:mod:`physrover.learn.curriculum`). 0: off,
    every episode at the domain's n_req (the paper's); c >= 1: the training episodes are
    played at coupling c (each POI's ``min(c, n_req)``), which goes up by one each time the
    champion team scores ``curriculum_threshold`` of the POIs' total value
    ``curriculum_patience`` generations in a row. The learning curve is always at the
    domain's coupling. A gradient-based trainer (``method = "mappo"``...) follows it too:
    its training episodes at the coupling, its deterministic policy's evaluation episodes
    (at the domain's coupling) rescored at it for the rule, logging points counted for
    generations (:meth:`~physrover.marl.common.Trainer.follow_curriculum`)."""
    curriculum_threshold: float = 0.5
    """The fraction of the POIs' total value (sum of V_k) the champion's mean G at the
    training coupling must reach for the coupling to tighten."""
    curriculum_patience: int = 10
    """Generations in a row (a trainer's: logging points) the champion must reach
    ``curriculum_threshold``."""
    checkpoint_every: int = 100
    """Write a checkpoint every this many generations (and at the end)."""

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
        check(self.generations >= 1, "generations", f"must be >= 1, got {self.generations}")
        check(self.seed >= 0, "seed", f"must be >= 0, got {self.seed}")
        check(self.population >= 2, "population", f"must be >= 2, got {self.population}")
        self.check_at_least(1, "hidden", "rollouts", "eval_episodes", "checkpoint_every")
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

    def _check_curriculum(self) -> None:
        """The coupling curriculum's options (those needing the domain: RunConfig's)."""
        check(self.curriculum_start >= 0, "curriculum_start",
              f"must be >= 0 (0: off), got {self.curriculum_start}")  # fmt: skip
        check(
            0.0 < self.curriculum_threshold <= 1.0,
            "curriculum_threshold",
            f"must be in (0, 1], a fraction of the POIs' total value, got "
            f"{self.curriculum_threshold}",
        )
        check(self.curriculum_patience >= 1, "curriculum_patience",
              f"must be >= 1, got {self.curriculum_patience}")  # fmt: skip
        if self.curriculum_start == 0:
            for name in ("curriculum_threshold", "curriculum_patience"):
                check(self.is_default(name), name,
                      "configures the coupling curriculum: set curriculum_start")  # fmt: skip

    def _check_ccea_options(self) -> None:
        """The CCEA's team formation, selection and mutation options."""
        check_choice(self.mutation, ("cauchy", "gauss"), "mutation")
        check_choice(self.activation, ("relu", "tanh"), "activation")
        check_choice(self.weight_init, ("fan-in", "uniform"), "weight_init")
        check_choice(self.team_formation, ("random", "softmax", "rank"), "team_formation")
        check_choice(self.selection, ("tournament", "elites"), "selection")
        check_choice(self.eval_team, ("champion", "best-team"), "eval_team")
        check(self.rollouts == 1 or self.method in ("D", "G"), "rollouts",
              f'averages one-episode fitness: method "D" or "G", got {self.method!r}')  # fmt: skip
        check(
            self.softmax_temperature > 0 and math.isfinite(self.softmax_temperature),
            "softmax_temperature",
            f"must be > 0, got {self.softmax_temperature}",
        )
        check(
            self.is_default("softmax_temperature") or self.team_formation == "softmax",
            "softmax_temperature",
            'configures team_formation = "softmax"',
        )
        spec = FITNESS_METHODS[self.method] if self.method in FITNESS_METHODS else None
        check(
            self.team_formation == "random" or not getattr(spec, "plans_teams", False),
            "team_formation",
            f"{self.method!r} plans its own teams; {self.team_formation} needs a method with "
            "random teams",
        )
        if self.selection != "elites":
            for name in ("n_individual_elites", "n_team_elites", "n_team_fitness_elites"):
                check(self.is_default(name), name, 'configures selection = "elites"')
            return
        check(
            1 <= self.n_individual_elites < self.population,
            "n_individual_elites",
            f'must be in [1, population) = [1, {self.population}) under selection = "elites" '
            f"(the champion is elite 0), got {self.n_individual_elites}",
        )
        check(self.n_team_elites >= 0, "n_team_elites", f"must be >= 0, got {self.n_team_elites}")
        check(0 <= self.n_team_fitness_elites < self.population - self.n_individual_elites,
              "n_team_fitness_elites", "must be >= 0 and leave room for one mutated offspring "
              f"beside the {self.n_individual_elites} fitness elites, got "
              f"{self.n_team_fitness_elites}")  # fmt: skip
