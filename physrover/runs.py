"""Run directories: resolved config, metrics.csv, champion snapshots, resumable state.

Layout of a run directory::

    config.toml                the resolved RunConfig
    metrics.csv                one row per generation (columns: physrover.learn.ccea)
    state.npz, state.json      the latest full state (populations, critics, replay buffers,
                               every RNG state), replaced atomically every checkpoint
    champions/gen_NNNNNN.npy   (R, P) genomes of the champion team at each checkpoint
    provenance.json            the code and machine of every start and resume
                               (physrover.provenance)

``train`` starts a run in a new (or empty) directory, or continues one with ``resume=True``;
a resumed run ends bit-identical to an uninterrupted one with the same seed.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import re
import signal
import tempfile
import threading
import warnings
import zipfile
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np

from physrover import plugins
from physrover.config import ConfigError, RunConfig
from physrover.learn.ccea import CCEA, GenerationStats, stats_header
from physrover.progress import Progress
from physrover.provenance import PROVENANCE, read_provenance, with_segment

CONFIG, METRICS, STATE_NPZ, STATE_PREV, STATE_JSON, CHAMPIONS = (
    "config.toml",
    "metrics.csv",
    "state.npz",
    "state.prev.npz",
    "state.json",
    "champions",
)
META_KEY = "__meta__"
"""state.npz's entry holding the checkpoint's metadata: its JSON text as uint8 bytes."""


class RunError(Exception):
    """A problem with a run directory, reported to the user in one line."""


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _fsync_dir(directory: Path) -> None:
    """Make the directory's entries (a rename into it) durable; a no-op where a directory
    cannot be opened (Windows)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _atomic_write(path: Path, data: bytes | str, previous: Path | None = None) -> None:
    """Replace ``path`` by ``data`` so that a kill at any instant leaves the old file or the
    new one, whole: written to a temporary file in the same directory, fsynced, renamed over
    ``path``, and the directory fsynced so the rename itself survives a crash.

    With ``previous``, the current ``path`` is first renamed to ``previous`` (the last good
    copy, kept until the next write): between the two renames ``path`` is missing and
    ``previous`` holds it. The file gets the permissions of a file opened the usual way
    (0666 less the umask), not mkstemp's private 0600, so colleagues read every file of a
    run alike. An OSError (disk full, ...) removes the temporary file and leaves ``path``
    as it was.
    """
    if isinstance(data, str):
        data = data.encode()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    tmp_path = Path(tmp)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view) :]
        os.fsync(fd)
        os.close(fd)
        fd = -1
        if previous is not None and path.exists():
            os.replace(path, previous)
        os.replace(tmp_path, path)
        _fsync_dir(path.parent)
    finally:
        if fd >= 0:
            os.close(fd)
        tmp_path.unlink(missing_ok=True)


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def save_state(run_dir: Path, learner) -> None:
    """Checkpoint a learner (the CCEA, or a gradient-based trainer: anything with
    ``state()``, ``generation`` and ``champion_genomes()``) into ``run_dir``.

    The checkpoint is one file, ``state.npz``, holding the arrays and the metadata (the
    JSON under ``__meta__``), replaced atomically; the one it replaces is kept as
    ``state.prev.npz``. The champion snapshot of the generation is written before it and
    ``state.json`` (a summary: the metadata, read by ``--status`` and the sweeps) after,
    so a kill at any instant leaves a checkpoint that :func:`load_state` resumes from.
    An OSError (a full disk) is a :class:`RunError` naming the file; the previous
    checkpoint stays intact.
    """
    arrays, meta = learner.state()
    generation = int(learner.generation)
    meta = {**meta, "generation": generation}
    meta_text = json.dumps(meta)
    arrays = {
        **arrays,
        "generation": np.array(generation),
        META_KEY: np.frombuffer(meta_text.encode(), dtype=np.uint8),
    }
    champions = run_dir / CHAMPIONS
    target = champions / f"gen_{generation:06d}.npy"
    try:
        champions.mkdir(exist_ok=True)
        buffer = io.BytesIO()
        np.save(buffer, learner.champion_genomes())
        _atomic_write(target, buffer.getvalue())
        target = run_dir / STATE_NPZ
        _atomic_write(target, _npz_bytes(arrays), previous=run_dir / STATE_PREV)
    except OSError as exc:
        raise RunError(f"cannot write the checkpoint of generation {generation}: {target}: "
                       f"{exc.strerror or exc}; {_intact(run_dir)}") from None  # fmt: skip
    try:
        _atomic_write(run_dir / STATE_JSON, meta_text)
    except OSError as exc:
        raise RunError(f"{run_dir / STATE_JSON}: {exc.strerror or exc}; the checkpoint of "
                       f"generation {generation} is saved in {STATE_NPZ}") from None  # fmt: skip


def _intact(run_dir: Path) -> str:
    """What a failed write leaves to resume from, for its error: the generation state.npz
    holds now (the new one, where only the directory's fsync failed)."""
    try:
        with np.load(run_dir / STATE_NPZ) as data:
            return f"the checkpoint of generation {int(data['generation'])} is intact"
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return "there is no earlier checkpoint"


def record_provenance(run_dir: Path, done: int, total: int) -> None:
    """Append this process's segment to ``run_dir``'s provenance.json
    (:func:`physrover.provenance.with_segment`, which warns of other code or another CPU)
    as it trains from generation ``done`` to ``total``; none when ``done >= total`` (a
    finished run resumed trains nothing)."""
    if done < total:
        segments = with_segment(run_dir, done)
        text = json.dumps({"segments": segments}, indent=1) + "\n"
        _atomic_write(run_dir / PROVENANCE, text)


def drop_state(run_dir: Path) -> int:
    """Delete a finished run's checkpoint (``state.npz`` and ``state.prev.npz``: populations,
    critics, replay buffers, ~18 MB each at paper scale); returns the bytes freed. config,
    metrics, champions and ``state.json`` stay, so curves, render, evaluate and a sweep's
    "done" check still work; the run can no longer be resumed or extended."""
    size = 0
    for path in (Path(run_dir) / STATE_NPZ, Path(run_dir) / STATE_PREV):
        with contextlib.suppress(FileNotFoundError):
            size += path.stat().st_size
            path.unlink()
    return size


class _Unreadable(Exception):
    """A checkpoint file that cannot be read whole (truncated, corrupted, inconsistent)."""


def _read_checkpoint(path: Path, run_dir: Path) -> tuple[dict[str, np.ndarray], dict]:
    """(arrays, meta) of one checkpoint file, every array read whole (the zip's CRC checked).

    A checkpoint of physrover 0.4 or earlier has no ``__meta__``: its metadata is
    ``state.json``, which must name the same generation."""
    try:
        with zipfile.ZipFile(path) as archive:  # np.load may stop short of a member's CRC
            damaged = archive.testzip()
        if damaged is not None:
            raise ValueError(f"{damaged} fails its CRC check")
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        generation = int(arrays.pop("generation"))
        if META_KEY in arrays:
            meta = json.loads(arrays.pop(META_KEY).tobytes().decode())
        else:
            meta = json.loads((run_dir / STATE_JSON).read_text())
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        raise _Unreadable(f"{path} cannot be read ({_reason(exc)})") from None
    if int(meta.get("generation", -1)) != generation:
        raise _Unreadable(f"{path} and {STATE_JSON} disagree: an interrupted checkpoint of "
                          "physrover 0.4 or earlier")  # fmt: skip
    return arrays, meta


def _reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    text = str(exc).strip().splitlines()
    name = type(exc).__name__
    return f"{name}: {text[0]}" if text else name


def load_state(run_dir: Path, learner) -> dict | None:
    """Restore the run's latest good checkpoint into ``learner`` (the CCEA or a trainer);
    returns its metadata (``generation``: completed generations), or None for a run that
    was never checkpointed.

    ``state.npz`` is read first. Where it is missing (a kill between the two renames of
    :func:`_atomic_write`) or cannot be read, ``state.prev.npz`` is, with a warning when
    ``state.npz`` was there but unreadable (it is moved aside to ``state.npz.bad``, so the
    next checkpoint does not push the good one out). Raises :class:`RunError`, in one line
    naming the file, when no checkpoint can be read, and when the state was dropped.
    """
    run_dir = Path(run_dir)
    current, previous = run_dir / STATE_NPZ, run_dir / STATE_PREV
    problem = None
    for path in (current, previous):
        if not path.exists():
            continue
        try:
            arrays, meta = _read_checkpoint(path, run_dir)
        except _Unreadable as exc:
            problem = problem or str(exc)
            continue
        genomes = getattr(learner, "genomes", None)
        if "genomes" in arrays and genomes is not None and arrays["genomes"].shape != genomes.shape:
            raise RunError(f"{path}: the saved state does not match {run_dir / CONFIG}")
        if problem is not None:
            os.replace(current, run_dir / (STATE_NPZ + ".bad"))
            resumed = f"resuming from {path.name} (generation {meta['generation']})"
            warnings.warn(f"{problem}; moved it to {STATE_NPZ}.bad, {resumed}", RuntimeWarning,
                          stacklevel=3)  # fmt: skip
        learner.load_state(arrays, meta)
        return meta
    if problem is not None:
        raise RunError(f"{problem}; there is no earlier checkpoint to resume from")
    if (run_dir / STATE_JSON).exists():
        generation = last_checkpoint(run_dir)
        raise RunError(
            f"{run_dir}: {STATE_NPZ} was dropped after generation {generation}; the "
            "run cannot be continued (its curves, champions and videos remain)"
        )
    return None


def resume_run(out: Path, learner, header: list[str]) -> list[dict]:
    """Continue the run in ``out`` where its last good checkpoint left it: restore the
    learner (:func:`load_state`), keep the metrics rows up to that generation (a kill after
    the checkpoint left newer ones, and perhaps a torn line), drop the champion snapshots
    after it (they are written again, identical), bring ``state.json`` in line and remove
    the temporary files a kill left. A run never checkpointed starts over. Returns the
    kept rows."""
    for stale in [*out.glob(".*.tmp"), *(out / CHAMPIONS).glob(".*.tmp")]:
        stale.unlink()  # a temporary file of _atomic_write that a kill left behind
    meta = load_state(out, learner)
    done = 0 if meta is None else int(meta["generation"])
    rows = [r for r in read_metrics(out / METRICS) if r["generation"] <= done] if meta else []
    _write_metrics(out / METRICS, rows, header)
    for generation, path in champion_checkpoints(out).items():
        if generation > done:
            path.unlink()
    if meta is not None and last_checkpoint(out) != done:
        _atomic_write(out / STATE_JSON, json.dumps(meta))
    return rows


def read_metrics(path: Path) -> list[dict[str, float]]:
    """The rows of a metrics.csv, generations counted from 1.

    physrover 0.1.0 counted the rows' generations from 0; such files (first row 0) are read
    shifted by one, so old and new runs plot on one axis. A last line without its line end
    (a process killed while writing it) is not a row.
    """
    with open(path, newline="") as f:
        text = f.read()
    lines = text.splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines.pop()
    rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(lines)]
    if rows and rows[0]["generation"] == 0:
        for row in rows:
            row["generation"] += 1
    return rows


def last_checkpoint(run_dir: Path) -> int | None:
    """Generations completed at the run's latest checkpoint, or None if it has none."""
    try:
        return int(json.loads((Path(run_dir) / STATE_JSON).read_text())["generation"])
    except (OSError, ValueError, KeyError):
        return None


def _write_metrics(path: Path, rows: list[dict], header: list[str] | None = None) -> None:
    header = header or stats_header()
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=header)
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _fmt(row[k]) for k in header})
    _atomic_write(path, text.getvalue())


def _fmt(value: float) -> str:
    if isinstance(value, int) or (
        isinstance(value, float) and value.is_integer() and abs(value) < 1e15
    ):
        return str(int(value))
    return "nan" if isinstance(value, float) and math.isnan(value) else repr(float(value))


def prepare_run_dir(out: Path, config: RunConfig, header: list[str] | None = None) -> None:
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise RunError(f"{out} exists and is not empty; use --resume {out} to continue it")
    out.mkdir(parents=True, exist_ok=True)
    _atomic_write(out / CONFIG, config.to_toml())
    _write_metrics(out / METRICS, [], header)


def find_runs(paths: list[str | Path]) -> list[Path]:
    """Run directories named in ``paths``, or found below them (e.g. a sweep's root)."""
    found: list[Path] = []
    for path in map(Path, paths):
        if (path / CONFIG).is_file():
            found.append(path)
        elif path.is_dir():
            found.extend(sorted(p.parent for p in path.rglob(CONFIG)))
        else:
            raise RunError(f"{path} is not a directory")
    return found


def load_run_config(run_dir: Path) -> RunConfig:
    if not (run_dir / CONFIG).is_file():
        raise RunError(f"{run_dir} is not a run directory (no {CONFIG})")
    try:
        return RunConfig.load(run_dir / CONFIG)
    except ConfigError as exc:
        made_with = {k for s in read_provenance(run_dir) for k in s.get("imports", {})}
        missing = sorted(made_with - set(plugins.loaded()))
        if not missing:
            raise
        raise ConfigError(exc.field, f"{exc.message}; the run was made with "
                          f"{' '.join('--import ' + m for m in missing)}") from None  # fmt: skip


def champion_checkpoints(run_dir: Path) -> dict[int, Path]:
    """{generation: path} of the champion snapshots of a run."""
    found = {}
    for path in (run_dir / CHAMPIONS).glob("gen_*.npy"):
        match = re.fullmatch(r"gen_(\d+)\.npy", path.name)
        if match:
            found[int(match.group(1))] = path
    return found


def load_champions(run_dir: Path, checkpoint: int | None = None) -> tuple[int, np.ndarray]:
    """(generation, (R, P) genomes) of the champion team at ``checkpoint`` (default: last)."""
    found = champion_checkpoints(run_dir)
    if not found:
        raise RunError(f"{run_dir} has no champion checkpoints yet")
    if checkpoint is None:
        checkpoint = max(found)
    if checkpoint not in found:
        raise RunError(f"no checkpoint {checkpoint} in {run_dir}; have {sorted(found)}")
    return checkpoint, np.load(found[checkpoint])


def _kernels_cached() -> bool:
    """Whether numba has cached this version's compiled kernels on disk (else the first
    generation compiles): their cache index files (``*.nbi``) under
    :func:`physrover.compiled.cache_dir`."""
    from physrover.compiled import cache_dir

    place = Path(cache_dir())
    return place.is_dir() and next(place.rglob("*kernels*.nbi"), None) is not None


def train(
    config: RunConfig | None,
    out: str | Path,
    *,
    resume: bool = False,
    generations: int | None = None,
    progress: bool = True,
    tensorboard: bool = False,
    on_generation: Callable[[GenerationStats], None] | None = None,
) -> Path:
    """Train (or continue) a run in ``out`` up to ``generations`` (default: the config's).

    With ``resume``, ``config`` is ignored and read from ``out``; the run continues from its
    last checkpoint (dropping metrics rows written after it) up to ``generations``. With
    ``tensorboard``, every metrics row is also written as TensorBoard scalars under
    ``out/tensorboard`` (needs ``pip install 'physrover[tensorboard]'``).
    """
    out = Path(out)
    if resume:
        config = load_run_config(out)
        if generations is not None and generations != config.learn.generations:
            config = config.with_overrides({"generations": generations})
            _atomic_write(out / CONFIG, config.to_toml())
    else:
        if config is None:
            raise ConfigError("config", "a config is needed to start a run")
        if generations is not None:
            config = config.with_overrides({"generations": generations})
    if config.trainer is not None:  # a gradient-based baseline, not the CCEA
        from physrover.trainer_runs import train_trainer

        return train_trainer(config, out, resume=resume, progress=progress,
                             tensorboard=tensorboard)  # fmt: skip
    if not resume:
        prepare_run_dir(out, config)
    log = TensorBoardLog(out) if tensorboard else None
    total = config.learn.generations
    bar = Progress(total, f"{config.learn.method} gen", unit="gen") if progress else None
    if bar:  # the first world reset and generation compile (or load) the kernels
        bar.warm_up("loading compiled kernels" if _kernels_cached()
                    else "compiling kernels, first run only")  # fmt: skip
    ccea = CCEA(config)
    rows = resume_run(out, ccea, stats_header()) if resume else []
    record_provenance(out, ccea.generation, total)

    latest: list[GenerationStats] = []

    def next_row() -> dict:
        latest[:] = [ccea.run_generation()]
        return asdict(latest[0])

    after = (lambda: on_generation(latest[0])) if on_generation else None
    write_rows(out, ccea, next_row, stats_header(), rows, total,
               config.learn.checkpoint_every, log, bar, restart_clock=True,
               after_row=after)  # fmt: skip
    return out


_stop_event = None
"""A sweep worker's stop: an event its pool sets when the sweep is interrupted
(:func:`set_stop_event`); None in a process of its own."""


def set_stop_event(event) -> None:
    """Make ``event`` (``is_set()``) this process's stop request instead of its own signals:
    what a sweep's pool workers do (:mod:`physrover.sweep`), which then leave the signals to
    the sweep's process."""
    global _stop_event
    _stop_event = event


class StopRequests:
    """``with StopRequests() as stop``: a Ctrl-C (SIGINT) or SIGTERM (a cluster's time limit,
    ``kill``) inside sets ``stop.requested`` to the signal's name instead of interrupting,
    so the training loop ends the generation, checkpoints it and stops; another SIGINT
    interrupts at once (KeyboardInterrupt; a repeated SIGTERM, as a cluster may send to
    every process of a job, is the same request). In a sweep's worker the request is the
    sweep's stop event (:func:`set_stop_event`) and "at once" is the sweep's SIGUSR1.
    Inside :meth:`held` (a checkpoint or a metrics row being written) an "at once" waits
    until the writing is done. Outside the main thread, where handlers cannot be installed,
    it does nothing. The previous handlers are restored on exit."""

    def __init__(self):
        self._requested: str | None = None
        self._previous: dict = {}
        self._holding = 0
        self._deferred = False

    @property
    def requested(self) -> str | None:
        """The signal's name once one came (or "the sweep's stop"), else None."""
        if self._requested is None and _stop_event is not None and _stop_event.is_set():
            self._requested = "the sweep's stop"
        return self._requested

    def _now(self) -> None:
        if self._holding:
            self._deferred = True  # raised when the writing is done (held's exit)
        else:
            raise KeyboardInterrupt

    def _handle(self, signum, frame) -> None:
        name = signal.Signals(signum).name
        if self._requested is not None and name == "SIGINT":
            self._now()
        self._requested = self._requested or name

    def __enter__(self) -> StopRequests:
        if threading.current_thread() is not threading.main_thread():
            return self
        if _stop_event is None:
            handlers = {signal.SIGINT: self._handle, signal.SIGTERM: self._handle}
        else:  # a sweep's worker: the sweep's process has the signals
            handlers = {getattr(signal, "SIGUSR1", None): lambda signum, frame: self._now()}
        for number, handler in handlers.items():
            if number is not None:
                self._previous[number] = signal.signal(number, handler)
        return self

    def __exit__(self, *exc) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, signal.SIG_DFL if handler is None else handler)

    @contextlib.contextmanager
    def held(self):
        """Inside, an interrupt "at once" waits (the handlers still run, whichever thread
        the signal reached, and record it): a second Ctrl-C cannot leave a checkpoint's two
        files, or a metrics row, half written."""
        self._holding += 1
        try:
            yield
        finally:
            self._holding -= 1
        if self._deferred and not self._holding:
            self._deferred = False
            raise KeyboardInterrupt


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
    the last generation lets the run finish. Closes ``log`` and ``bar``."""
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
                        writer.writerow({k: _fmt(v) for k, v in row.items()})
                        if done % every == 0 or done == total:
                            f.flush()
                    except OSError as exc:  # a full disk: say so, as a checkpoint does
                        reason = f"{exc.strerror or exc}; {_intact(out)}"
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
                    raise KeyboardInterrupt(f"stopped by {stop.requested} after generation {done}")
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
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError:
            raise RunError(
                "--tensorboard needs the tensorboard package: pip install 'physrover[tensorboard]'"
            ) from None
        self.writer = SummaryWriter(log_dir=str(out / "tensorboard"))

    def write_row(self, row: dict) -> None:
        """One metrics row ({column: value}, with ``generation`` the step)."""
        row = dict(row)
        step = row.pop("generation")
        for name, value in row.items():
            self.writer.add_scalar(name, value, global_step=step)

    def close(self) -> None:
        self.writer.close()
