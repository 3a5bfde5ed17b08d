"""Training a run: :func:`train` starts a run in a new (or empty) directory, or continues one
with ``resume=True``; a resumed run ends bit-identical to an uninterrupted one with the same
seed. One run loop for every learner (:func:`_train_claimed`): the CCEA
(:class:`CCEALearner`) and the gradient-based trainers
(:class:`~physrover.experiment.trainer_runs.TrainerLearner`), each with its own metrics
columns, on the store (:mod:`physrover.experiment.store`) and the loop
(:mod:`physrover.experiment.loop`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Protocol

from physrover.config import ConfigError, RunConfig
from physrover.core.progress import Progress
from physrover.experiment.claims import claim
from physrover.experiment.loop import TensorBoardLog, write_rows
from physrover.experiment.store import (
    CONFIG,
    atomic_write,
    check_new,
    load_run_config,
    prepare_run_dir,
    record_provenance,
    resume_run,
)
from physrover.learn.ccea import CCEA
from physrover.learn.stats import GenerationStats, stats_header, stats_row


def _kernels_cached() -> bool:
    """Whether numba has cached this version's compiled kernels on disk (else the first
    generation compiles): their cache index files (``*.nbi``) under
    :func:`physrover.core.compiled.cache_dir`."""
    from physrover.core.compiled import cache_dir

    place = Path(cache_dir())
    return place.is_dir() and next(place.rglob("*kernels*.nbi"), None) is not None


def train(
    config: RunConfig | None,
    out: str | Path,
    *,
    resume: bool = False,
    generations: int | None = None,
    iterations: int | None = None,
    progress: bool = True,
    tensorboard: bool = False,
    on_generation: Callable[[GenerationStats], None] | None = None,
    on_resumed: Callable[[int], None] | None = None,
) -> Path:
    """Train (or continue) a run in ``out`` up to its length: ``generations`` for the CCEA,
    ``iterations`` for a gradient-based trainer (``num_envs`` episodes each; its
    total_episodes becomes iterations x num_envs), by default the config's. The other unit
    is a ConfigError, as is a length below 1: nothing is written then.

    With ``resume``, ``config`` is ignored and read from ``out``; the run continues from its
    last checkpoint (dropping metrics rows written after it) up to that length. With
    ``tensorboard``, every metrics row is also written as TensorBoard scalars under
    ``out/tensorboard`` (needs ``pip install 'physrover[tensorboard]'``, checked first).

    ``on_resumed(generation)`` is called once a resume has loaded its checkpoint (0: none
    yet, the run starts over). The run is claimed while it trains
    (:mod:`physrover.experiment.claims`): another process training ``out`` raises
    :class:`~physrover.experiment.claims.RunHeld` at once, naming it.
    """
    out = Path(out)
    if resume:
        config = load_run_config(out)
    elif config is None:
        raise ConfigError("config", "a config is needed to start a run")
    lengthened = False
    for unit, n in (("generation", generations), ("iteration", iterations)):
        if n is not None and (unit != config.unit or n != config.length):
            config = config.with_length(n, unit)
            lengthened = True
    if tensorboard:
        TensorBoardLog.check_installed()
    if not resume:
        check_new(out)  # before the claim makes the directory
    with claim(out):  # one process trains a run at a time (physrover.experiment.claims)
        if resume and lengthened:
            atomic_write(out / CONFIG, config.to_toml())
        return _train_claimed(config, out, resume, progress, tensorboard, on_generation,
                              on_resumed)  # fmt: skip


class CCEALearner:
    """The CCEA as the run loop drives it (:class:`RunLearner`)."""

    unit, bar_unit, warms_up = "generation", "gen", True

    def __init__(self, config: RunConfig, on_generation=None):
        self.config = config
        self.columns = stats_header(curriculum=config.learn.curriculum_start > 0,
                                    hybrid=config.hybrid is not None)  # fmt: skip
        self.label = f"{config.learn.method} gen"
        self.total = config.learn.generations
        self.on_generation = on_generation
        self.model: CCEA | None = None
        self.latest: GenerationStats | None = None

    def build(self) -> CCEA:
        self.model = CCEA(self.config)
        return self.model

    def next_row(self) -> dict:
        self.latest = self.model.run_generation()
        return stats_row(self.latest, self.columns)

    def after_row(self) -> None:
        if self.on_generation:
            self.on_generation(self.latest)


class RunLearner(Protocol):
    """What the one run loop needs of a learner (the CCEA's :class:`CCEALearner`, a
    trainer's :class:`~physrover.experiment.trainer_runs.TrainerLearner`): the metrics
    ``columns`` (the first: its unit), the ``unit`` of a row ("generation", "iteration")
    and of the progress bar, its ``total``, a ``build()`` that makes the model (whose
    ``generation`` counts the rows done and whose ``state()`` / ``load_state()`` are the
    checkpoints), and ``next_row()``, which advances it by one row."""

    unit: str
    bar_unit: str
    warms_up: bool
    label: str
    columns: list[str]
    total: int

    def build(self): ...

    def next_row(self) -> dict: ...


def learner_for(config: RunConfig, out: Path, resume: bool, on_generation=None) -> RunLearner:
    """The learner of ``config``: a gradient-based trainer's, else the CCEA's."""
    if config.trainer is not None:
        from physrover.experiment.trainer_runs import TrainerLearner

        return TrainerLearner(config, out, resume)
    return CCEALearner(config, on_generation)


def _train_claimed(config: RunConfig, out: Path, resume: bool, progress: bool,
                   tensorboard: bool, on_generation, on_resumed) -> Path:  # fmt: skip
    """:func:`train` once the run is claimed: the one run loop of every learner (prepare,
    resume, provenance, progress, metrics, checkpoints and stops)."""
    learner = learner_for(config, out, resume, on_generation)
    if not resume:
        prepare_run_dir(out, config, learner.columns)
    log = TensorBoardLog(out) if tensorboard else None
    bar = Progress(learner.total, learner.label, unit=learner.bar_unit) if progress else None
    if bar and learner.warms_up:  # the first world reset and generation compile the kernels
        bar.warm_up("loading compiled kernels" if _kernels_cached()
                    else "compiling kernels, first run only")  # fmt: skip
    model = learner.build()
    rows = resume_run(out, model, learner.columns) if resume else []
    if resume and on_resumed:
        on_resumed(model.generation)
    record_provenance(out, model.generation, learner.total)
    write_rows(out, model, learner.next_row, learner.columns, rows, learner.total,
               config.learn.checkpoint_every, log, bar, restart_clock=True,
               after_row=getattr(learner, "after_row", None), unit=learner.unit)  # fmt: skip
    return out
