"""The fitness methods' own settings: each a typed, validated TOML table beside ``[learn]``.

A fitness method that has settings names their class when it is registered
(:func:`physrover.learn.fitness.register_method`), as a gradient-based trainer names its
``[mappo]``-style table (:mod:`physrover.marl.configs`); ``[learn]`` keeps what every method
shares (the CCEA's population, mutation, selection, feedback, ...). The tables:

- ``[sampled]`` (:class:`SampledConfig`): ``average`` and ``leniency``;
- ``[critic]`` (:class:`CriticConfig`): the paper's fitness critics, ``mean-critic``,
  ``max-critic``, ``max-critic-regular`` and ``mean-critic-inexact``;
- ``[trajectory_critic]`` (:class:`TrajectoryCriticConfig`): ``gru-critic``,
  ``gru-sum-critic``, ``recurrent-max-critic`` and ``attention-critic``.

A setting given to a method that does not have it is an error naming both. Field names are
those physrover 0.5 had in ``[learn]`` (so ``--set critic_lr=...``, sweep grids and run
folders' names read as before); a 0.5 ``[learn]`` that still holds them is read with a
one-line note (:meth:`physrover.config.RunConfig.from_dict`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

from physrover.config import OPTIMIZERS, ConfigBase, check, check_choice
from physrover.core.registry import FITNESS_METHODS
from physrover.domain.scoring.credit import team_credit


@dataclasses.dataclass(frozen=True)
class SampledConfig(ConfigBase):
    """``average`` and ``leniency`` (paper Section 2.3 and Section 4's "average of 10
    episodes"): a policy's fitness is the mean, or the max, of its feedback over
    ``n_samples`` episodes, each with freshly drawn teammates."""

    section: ClassVar[str] = "sampled"

    n_samples: int = 10
    """Episodes per policy per generation (rounds of k teams)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        self.check_at_least(1, "n_samples")


@dataclasses.dataclass(frozen=True)
class _CriticNetwork(ConfigBase):
    """The per-pair intermediate critic and the trajectory replay, which both the paper's
    critics and the recurrent max critic have."""

    critic_hidden: int = 80
    """Hidden units of the intermediate critic (pair -> hidden -> 1, leaky ReLU; the
    paper's 10 -> 80 -> 1)."""
    leaky_slope: float = 0.01
    """Slope of the critic's leaky ReLU for negative inputs."""
    critic_lr: float = 5e-6
    """Critic learning rate alpha_w (Eqs. 7, 9); 0 freezes the critic at its random
    initialisation (an ablation: is it the training or the random shape that helps?)."""
    critic_optimizer: str = "sgd"
    """"sgd": plain mini-batch gradient steps of Eq. 7/9; "adam": Adam on the same gradient."""
    replay_trajectories: int = 500
    """Replay capacity, trajectories per rover, for regular updates (and trajectory critics)."""
    trajectory_batch: int = 7
    """Trajectories per mini-batch, regular updates (and trajectory critics)."""
    trajectory_batches: int = 7
    """Mini-batches per generation, regular updates (and trajectory critics)."""

    def __post_init__(self) -> None:
        self._coerce_fields()
        check_choice(self.critic_optimizer, OPTIMIZERS, "critic_optimizer")
        self.check_at_least(1, "critic_hidden", "replay_trajectories", "trajectory_batch",
                            "trajectory_batches")  # fmt: skip
        check(self.critic_lr >= 0 and math.isfinite(self.critic_lr), "critic_lr", "must be "
              f">= 0 (0 freezes the critic at its random start), got {self.critic_lr}")  # fmt: skip
        check(0.0 <= self.leaky_slope < 1.0, "leaky_slope",
              f"must be in [0, 1), got {self.leaky_slope}")  # fmt: skip


@dataclasses.dataclass(frozen=True)
class CriticConfig(_CriticNetwork):
    """The paper's fitness critics (Section 3): a per-pair intermediate critic per rover,
    aggregated over the trajectory by its mean (Eq. 4) or max (Eq. 3), trained by regular
    updates (whole trajectories, Eqs. 6-8) or inexact ones (pairs, Eqs. 9-10). Defaults are
    the paper's; the fields marked "beyond the paper" are this project's extensions."""

    section: ClassVar[str] = "critic"

    critic_step_input: bool = False
    """Beyond the paper: the critic also sees the pair's step t / (T - 1) as an input (11
    inputs with the paper's sensor); off is the paper's critic."""
    critic_top_k: int = 1
    """Beyond the paper: the max critic's fitness is the mean of the k largest critic values
    along the trajectory (1: their max, Eq. 3, the paper's). ``max-critic`` only."""
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
    replay_pairs: int = 25000
    """Replay capacity, state-action pairs per rover, for inexact updates."""
    pair_batch: int = 50
    """State-action pairs per mini-batch, inexact updates."""
    pair_batches: int = 50
    """Mini-batches per generation, inexact updates."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_choice(self.critic_output_weights, ("fixed", "trained"), "critic_output_weights")
        check_choice(self.critic_target, ("episode", "step"), "critic_target")
        self.check_at_least(1, "critic_top_k", "critic_ensemble", "replay_pairs", "pair_batch",
                            "pair_batches")  # fmt: skip
        check(self.critic_optimism >= 0 and math.isfinite(self.critic_optimism),
              "critic_optimism", f"must be >= 0, got {self.critic_optimism}")  # fmt: skip
        check(self.critic_optimism == 0 or self.critic_ensemble > 1, "critic_optimism",
              "an ensemble's spread needs critic_ensemble > 1")  # fmt: skip

    def check_run(self, run) -> None:
        """The rules across a run's tables (:class:`~physrover.config.RunConfig`): which
        critic ``[learn] method`` names, and per-step targets' credit and POIs."""
        method = run.learn.method
        check(self.is_default("critic_top_k") or method == "max-critic", "critic_top_k",
              f"a softer max is for the max critic (inexact updates), not {method!r}")  # fmt: skip
        if self.critic_target == "episode":
            return
        check(FITNESS_METHODS[method].pair_replay, "critic_target",
              "per-step targets need a critic that replays pairs (inexact updates: "
              f"max-critic, mean-critic-inexact), not {method!r}")  # fmt: skip
        credit = team_credit(run.learn.feedback, run.domain)
        check(getattr(credit, "per_step_defined", False), "critic_target",
              'per-step targets are defined for feedback "D", "G" and "D++" (and no class\'s '
              f"feedback_plus_G), not {run.learn.feedback!r}")  # fmt: skip
        check(
            not any(p.scored_by_rule for p in run.domain.pois),
            "critic_target",
            'per-step targets need POIs without after, require, score_at = "final" or '
            'value_by = "distance"',
        )


@dataclasses.dataclass(frozen=True)
class TrajectoryCriticConfig(_CriticNetwork):
    """Beyond the paper, trajectory critics (:mod:`physrover.learn.trajectory_critics`): a
    network over the whole episode per rover, trained on the last ``replay_trajectories``
    trajectories, ``trajectory_batches`` mini-batches of ``trajectory_batch`` a
    generation. ``recurrent-max-critic``'s per-pair critic has ``critic_hidden`` units of
    slope ``leaky_slope`` and learns at ``critic_lr`` with ``critic_optimizer`` on the
    squared error, as the paper's; the others learn at ``trajectory_lr`` with Adam on
    ``trajectory_loss``."""

    section: ClassVar[str] = "trajectory_critic"

    trajectory_loss: str = "mse"
    """"mse" (the value) or "rank" (a logistic loss on the order of each pair of
    trajectories in a mini-batch)."""
    trajectory_hidden: int = 32
    """Hidden size of a trajectory critic (the GRU's state, the attention's embedding)."""
    trajectory_lr: float = 1e-3
    """Adam's learning rate for a trajectory critic."""

    def __post_init__(self) -> None:
        super().__post_init__()
        check_choice(self.trajectory_loss, ("mse", "rank"), "trajectory_loss")
        self.check_at_least(1, "trajectory_hidden")
        self.check_positive("trajectory_lr")

    def check_run(self, run) -> None:
        """``recurrent-max-critic`` learns as the paper's critic (module docstring)."""
        if run.learn.method == "recurrent-max-critic":
            for name in ("trajectory_loss", "trajectory_lr"):
                check(self.is_default(name), name, "recurrent-max-critic learns as the paper's "
                      "critic (critic_lr and critic_optimizer, every step's value on the "
                      "squared error)")  # fmt: skip
