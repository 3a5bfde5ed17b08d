"""Run directories of the gradient-based trainers (``physrover train --method mappo|maddpg``).

The same layout as a CCEA run (:mod:`physrover.experiment.store`): config.toml (with the
trainer's table, e.g. ``[mappo]``), metrics.csv, ``champions/gen_N.npy`` (the current
policies as CCEA genomes, so ``render`` and ``evaluate`` play them), state.npz/state.json
(networks, optimisers, replay buffer, every generator), and a resumed run bit-identical to
an uninterrupted one. A row of metrics.csv is one iteration (``generation`` counts
iterations, from 1) with the CCEA's columns plus ``episodes`` and ``env_steps``: training
episodes and team steps so far, the axis ``physrover curves --x episodes`` draws.
``fitness_mean`` is NaN (there is none); ``critic_loss`` is the value loss (MAPPO) or the
critics' loss (MADDPG). The run's length is the trainer's ``total_episodes``.
"""

from __future__ import annotations

import math
from pathlib import Path

from physrover.config import RunConfig
from physrover.core.progress import Progress
from physrover.core.registry import TRAINERS
from physrover.experiment.loop import TensorBoardLog, write_rows
from physrover.experiment.store import (
    load_run_config,
    prepare_run_dir,
    record_provenance,
    resume_run,
)
from physrover.learn.ccea import stats_header

EXTRA_COLUMNS = ["episodes", "env_steps"]


def metrics_header() -> list[str]:
    """metrics.csv columns of a trainer's run: the CCEA's, then episodes and env_steps."""
    return stats_header() + EXTRA_COLUMNS


def metrics_row(stats: dict) -> dict:
    """A metrics.csv row from the dict a trainer's ``iteration()`` returns."""
    loss = stats.get("value_loss", stats.get("critic_loss", math.nan))
    return {
        "generation": int(stats["iteration"]),
        "eval_G": float(stats.get("eval_G", math.nan)),
        "train_G_mean": float(stats["train_G_mean"]),
        "fitness_mean": math.nan,
        "critic_loss": float(loss),
        "wall_seconds": float(stats["wall_seconds"]),
        "episodes": int(stats["episodes"]),
        "env_steps": int(stats["env_steps"]),
    }


def train_trainer(
    config: RunConfig,
    out: str | Path,
    *,
    resume: bool,
    progress: bool,
    tensorboard: bool,
    on_resumed=None,
) -> Path:
    """Train (or continue, with ``resume``) a gradient-based baseline in run directory ``out``."""
    out = Path(out)
    if resume:
        config = load_run_config(out)
    else:
        prepare_run_dir(out, config, metrics_header())
    spec = TRAINERS[config.learn.method]
    trainer = spec.load()(config.trainer, config.domain)
    rows = resume_run(out, trainer, metrics_header()) if resume else []
    if resume and on_resumed:  # training.train's, once the checkpoint has loaded
        on_resumed(trainer.iterations)
    record_provenance(out, trainer.iterations, trainer.total_iterations)
    log = TensorBoardLog(out) if tensorboard else None
    total = trainer.total_iterations
    label = f"{config.learn.method} iteration"
    bar = Progress(total, label, trainer.iterations, unit="it") if progress else None
    write_rows(out, trainer, lambda: metrics_row(trainer.iteration()), metrics_header(), rows,
               total, config.learn.checkpoint_every, log, bar, unit="iteration")  # fmt: skip
    return out
