"""A CCEA generation's row of metrics.csv: :class:`GenerationStats` and its columns."""

from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass(frozen=True)
class GenerationStats:
    """One row of metrics.csv."""

    generation: int
    """The generation's number, counted from 1."""
    eval_G: float
    """Mean G of the champion team (chosen by the previous generation; or the previous
    generation's best team, ``eval_team``) on ``eval_episodes`` fresh episodes: the learning
    curve."""
    train_G_mean: float
    """Mean G over this generation's training episodes (the population's teams)."""
    fitness_mean: float
    """Mean fitness the method assigned (D, a critic's value, ...; its scale is the
    method's own)."""
    critic_loss: float
    """The critic's mean squared error in this generation's updates (NaN without a critic)."""
    wall_seconds: float
    """Seconds spent in generations since the run started, summed across resumes; includes
    compiling the kernels on a first run, excludes writing checkpoints."""
    train_n_req: int = 0
    """The largest coupling the training episodes were played at, under a coupling
    curriculum (:mod:`physrover.learn.curriculum`; a metrics.csv column only then)."""
    learner_G: float = float("nan")
    """Mean G of the hybrid learner's training episodes in this generation (NaN where it
    did not train; :mod:`physrover.learn.hybrid`; a metrics.csv column only then)."""


def stats_header(curriculum: bool = False, hybrid: bool = False) -> list[str]:
    """metrics.csv's columns: :class:`GenerationStats`' fields, ``train_n_req`` only under a
    coupling curriculum, ``learner_G`` only with a hybrid learner."""
    dropped = {"train_n_req": not curriculum, "learner_G": not hybrid}
    return [f.name for f in fields(GenerationStats) if not dropped.get(f.name)]


def stats_row(stats: GenerationStats, header: list[str]) -> dict:
    """A metrics.csv row of ``header``'s columns."""
    return {name: getattr(stats, name) for name in header}
