"""Training a run: :func:`train` starts a run in a new (or empty) directory, or continues one
with ``resume=True``; a resumed run ends bit-identical to an uninterrupted one with the same
seed. The CCEA trains here; a gradient-based trainer's run goes to
:mod:`physrover.experiment.trainer_runs`. Both use the store
(:mod:`physrover.experiment.store`) and the loop (:mod:`physrover.experiment.loop`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

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
from physrover.learn.ccea import CCEA, GenerationStats, stats_header, stats_row


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


def _train_claimed(config: RunConfig, out: Path, resume: bool, progress: bool,
                   tensorboard: bool, on_generation, on_resumed) -> Path:  # fmt: skip
    """:func:`train` once the run is claimed."""
    if config.trainer is not None:  # a gradient-based baseline, not the CCEA
        from physrover.experiment.trainer_runs import train_trainer

        return train_trainer(config, out, resume=resume, progress=progress,
                             tensorboard=tensorboard, on_resumed=on_resumed)  # fmt: skip
    header = stats_header(curriculum=config.learn.curriculum_start > 0)
    if not resume:
        prepare_run_dir(out, config, header)
    log = TensorBoardLog(out) if tensorboard else None
    total = config.learn.generations
    bar = Progress(total, f"{config.learn.method} gen", unit="gen") if progress else None
    if bar:  # the first world reset and generation compile (or load) the kernels
        bar.warm_up("loading compiled kernels" if _kernels_cached()
                    else "compiling kernels, first run only")  # fmt: skip
    ccea = CCEA(config)
    rows = resume_run(out, ccea, header) if resume else []
    if resume and on_resumed:
        on_resumed(ccea.generation)
    record_provenance(out, ccea.generation, total)

    latest: list[GenerationStats] = []

    def next_row() -> dict:
        latest[:] = [ccea.run_generation()]
        return stats_row(latest[0], header)

    after = (lambda: on_generation(latest[0])) if on_generation else None
    write_rows(out, ccea, next_row, header, rows, total,
               config.learn.checkpoint_every, log, bar, restart_clock=True,
               after_row=after)  # fmt: skip
    return out
