"""The training loop every learner shares (the CCEA and the gradient-based trainers): one
metrics row per generation, checkpoints on schedule and at stops, TensorBoard scalars and
the progress bar.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from pathlib import Path

from physrover.core.progress import Progress
from physrover.experiment.stops import StopRequests
from physrover.experiment.store import (
    METRICS,
    RunError,
    format_value,
    intact_checkpoint,
    last_checkpoint,
    save_state,
)


def write_rows(
    out: Path,
    learner,
    next_row: Callable[[], dict],
    header: list[str],
    rows: list[dict],
    total: int,
    every: int,
    log: TensorBoardLog | None,
    bar: Progress | None,
    restart_clock: bool = False,
    after_row: Callable[[], None] | None = None,
    unit: str = "generation",
) -> None:
    """The training loop of every learner (the CCEA, a gradient-based trainer): append
    ``next_row()`` to metrics.csv until ``learner.generation`` reaches ``total``,
    checkpointing every ``every`` generations and at the end (and once at all, for a run
    already complete), with TensorBoard scalars and the progress bar (its best eval G
    starting from ``rows``, the rows kept from before a resume; ``restart_clock``: its rate
    counts from the end of the first generation, which compiles or loads the kernels);
    ``after_row()`` is called once each row is written and checkpointed. A Ctrl-C or
    SIGTERM ends the current generation (its row written, logged and shown), checkpoints it
    and raises KeyboardInterrupt (:class:`StopRequests`), so a resume loses nothing; one in
    the last generation lets the run finish. ``unit``: what a row is, in messages
    ("generation", or a trainer's "iteration"). Closes ``log`` and ``bar``."""
    best = max((r["eval_G"] for r in rows), default=math.nan)
    saved = learner.generation
    try:
        with open(out / METRICS, "a", newline="") as f, StopRequests() as stop:
            writer = csv.DictWriter(f, fieldnames=header)
            first = restart_clock
            while learner.generation < total:
                row = next_row()
                done = learner.generation
                with stop.held():
                    try:
                        writer.writerow({k: format_value(v) for k, v in row.items()})
                        if done % every == 0 or done == total:
                            f.flush()
                    except OSError as exc:  # a full disk: say so, as a checkpoint does
                        reason = f"{exc.strerror or exc}; {intact_checkpoint(out)}"
                        raise RunError(f"cannot write {out / METRICS}: {reason}") from None
                    if done % every == 0 or done == total:
                        save_state(out, learner)
                        saved = done
                if not math.isnan(row["eval_G"]):
                    best = row["eval_G"] if math.isnan(best) else max(best, row["eval_G"])
                if log:
                    log.write_row(row)
                if after_row:
                    after_row()
                if bar:
                    if first:
                        bar.restart_clock(done)
                        first = False
                    bar.update(done, **{"eval G": row["eval_G"], "best G": best})
                if stop.requested and done < total:  # resume goes on from this generation
                    with stop.held():
                        if saved != done:
                            f.flush()
                            save_state(out, learner)
                    raise KeyboardInterrupt(f"stopped by {stop.requested} after {unit} {done}")
    finally:
        if bar:
            bar.close()
        if log:
            log.close()
    if last_checkpoint(out) != learner.generation:  # a finished run resumed: none yet
        save_state(out, learner)


class TensorBoardLog:
    """The metrics.csv scalars as TensorBoard events (``out/tensorboard``), step = generation.

    metrics.csv stays the record; this is for viewing (``tensorboard --logdir runs``). A
    resumed run appends to the same directory; TensorBoard shows the latest value of a step.
    """

    def __init__(self, out: Path):
        self.check_installed()
        from torch.utils.tensorboard import SummaryWriter

        self.writer = SummaryWriter(log_dir=str(out / "tensorboard"))

    @staticmethod
    def check_installed() -> None:
        """RunError unless TensorBoard's writer imports: asked before a run directory is
        made, so a missing package leaves nothing half made."""
        try:
            from torch.utils.tensorboard import SummaryWriter  # noqa: F401
        except ImportError:
            raise RunError(
                "--tensorboard needs the tensorboard package: pip install 'physrover[tensorboard]'"
            ) from None

    def write_row(self, row: dict) -> None:
        """One metrics row ({column: value}, its first column the step: ``generation``, or a
        trainer's ``iteration``)."""
        row = dict(row)
        step = row.pop(next(iter(row)))
        for name, value in row.items():
            self.writer.add_scalar(name, value, global_step=step)

    def close(self) -> None:
        self.writer.close()
