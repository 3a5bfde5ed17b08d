"""Run directories of the gradient-based trainers (``physrover train --method mappo|maddpg``).

The same layout as a CCEA run (:mod:`physrover.experiment.store`): config.toml (with the
trainer's table, e.g. ``[mappo]``), metrics.csv, ``champions/gen_N.npy`` (the current
policies as CCEA genomes, so ``render`` and ``evaluate`` play them), state.npz/state.json
(networks, optimisers, replay buffer, every generator), and a resumed run bit-identical to
an uninterrupted one; trained by the one run loop (:mod:`physrover.experiment.training`).

A row of metrics.csv is one iteration, in columns named for what they hold:
``iteration`` (from 1), ``eval_G``, ``train_G_mean``, under a coupling curriculum
``train_n_req`` (the coupling the iteration trained at), the trainer's own losses
(``Trainer.STATS``: MAPPO's and IPPO's ``policy_loss``, ``value_loss``, ``entropy``,
``approx_kl``, ``clip_fraction``, ``std``; MADDPG's ``critic_loss``, ``actor_loss``,
``q_mean``, ``updates``), ``wall_seconds``, then ``episodes`` and ``env_steps`` (training
episodes and team steps so far, the axis ``physrover curves --x episodes`` draws). The
run's length is the trainer's ``total_episodes``. Runs of physrover 0.4 and 0.5 wrote the
CCEA's columns instead (:data:`LEGACY_COLUMNS`: ``generation`` holding the iteration,
``critic_loss`` the value loss, ``fitness_mean`` NaN); they resume in their own columns.
"""

from __future__ import annotations

import math
from pathlib import Path

from physrover.config import RunConfig
from physrover.core.registry import TRAINERS
from physrover.experiment.store import METRICS, metrics_columns
from physrover.learn.curriculum import CouplingCurriculum
from physrover.learn.stats import stats_header

LEGACY_COLUMNS = stats_header() + ["episodes", "env_steps"]
"""metrics.csv columns of a trainer's run made by physrover 0.4 or 0.5."""


def trainer_columns(trainer_class, curriculum: bool = False) -> list[str]:
    """metrics.csv columns of a run of ``trainer_class`` (module docstring), with
    ``train_n_req`` under a coupling curriculum."""
    coupling = ["train_n_req"] if curriculum else []
    return ["iteration", "eval_G", "train_G_mean", *coupling, *trainer_class.STATS,
            "wall_seconds", "episodes", "env_steps"]  # fmt: skip


def trainer_row(stats: dict, columns: list[str]) -> dict:
    """A metrics.csv row in ``columns`` from the dict a trainer's ``iteration()`` returns
    (in :data:`LEGACY_COLUMNS` for a run of physrover 0.4-0.5)."""
    if columns == LEGACY_COLUMNS:
        loss = stats.get("value_loss", stats.get("critic_loss", math.nan))
        stats = {**stats, "generation": stats["iteration"], "fitness_mean": math.nan,
                 "critic_loss": loss}  # fmt: skip
    return {name: float(stats.get(name, math.nan)) for name in columns} | {
        columns[0]: int(stats["iteration"]),
        "episodes": int(stats["episodes"]),
        "env_steps": int(stats["env_steps"]),
    }


def build_trainer(config: RunConfig, trainer_config=None):
    """The gradient-based trainer of ``config`` (built from its ``[mappo]``... table, or
    from ``trainer_config`` in its place), following the run's coupling curriculum
    (``[learn] curriculum_start``) if it has one."""
    trainer_class = TRAINERS[config.learn.method].load()
    trainer = trainer_class(trainer_config or config.trainer, config.domain)
    curriculum = CouplingCurriculum.of(config)  # or None
    if curriculum is not None:
        trainer.follow_curriculum(curriculum)
    return trainer


class TrainerLearner:
    """A gradient-based trainer as the run loop drives it (:class:`RunLearner`)."""

    unit, bar_unit, warms_up = "iteration", "it", False

    def __init__(self, config: RunConfig, out: Path, resume: bool):
        self.config = config
        self.trainer_class = TRAINERS[config.learn.method].load()
        own = metrics_columns(out / METRICS) if resume else None
        curriculum = config.learn.curriculum_start > 0
        self.columns = own if own == LEGACY_COLUMNS else trainer_columns(self.trainer_class,
                                                                         curriculum)  # fmt: skip
        self.label = f"{config.learn.method} iteration"
        self.total = config.trainer.total_iterations
        self.model = None

    def build(self):
        self.model = build_trainer(self.config)
        return self.model

    def next_row(self) -> dict:
        return trainer_row(self.model.iteration(), self.columns)
