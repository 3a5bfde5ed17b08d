"""The run-directory store: where a run lives on disk, and how it is written so that a kill
at any instant leaves a run that resumes.

Layout of a run directory::

    config.toml                the resolved RunConfig
    metrics.csv                one row per generation (columns: physrover.learn.ccea)
    state.npz                  the checkpoint: every array and the metadata (``__meta__``)
                               in one file, replaced atomically every checkpoint
    state.prev.npz             the checkpoint before it (the fallback for a damaged one)
    state.json                 a summary of the checkpoint's metadata (``--status``, sweeps)
    champions/gen_NNNNNN.npy   (R, P) genomes of the champion team at each checkpoint
    provenance.json            the code and machine of every start and resume
                               (physrover.experiment.provenance)
    .claim                     locked while a process trains the run (experiment.claims)

Every file is replaced through :func:`atomic_write` (temporary file, fsync, rename,
directory fsync) but the rows the training loop appends to metrics.csv, where a line torn
by a kill is not read and a resume drops the rows past its checkpoint. This module knows
nothing of how a run trains (:mod:`physrover.experiment.training`); it takes any learner
with ``state()``, ``load_state()``, ``generation`` and ``champion_genomes()``.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import tempfile
import warnings
import zipfile
from pathlib import Path

import numpy as np

from physrover.config import ConfigError, RunConfig
from physrover.core import plugins
from physrover.experiment.metrics_file import (  # noqa: F401  (read_metrics: the store's too)
    format_value,
    metrics_columns,
    metrics_text,
    read_metrics,
)
from physrover.experiment.provenance import PROVENANCE, read_provenance, with_segment
from physrover.learn.stats import stats_header

CONFIG, METRICS, STATE_NPZ, STATE_PREV, STATE_JSON, CHAMPIONS = (
    "config.toml",
    "metrics.csv",
    "state.npz",
    "state.prev.npz",
    "state.json",
    "champions",
)
META_KEY = "__meta__"  # state.npz's entry of the checkpoint's metadata: JSON as uint8 bytes
CLAIM = ".claim"  # the file a process locks while it trains the run (experiment.claims)


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


def atomic_write(path: Path, data: bytes | str, previous: Path | None = None) -> None:
    """Replace ``path`` by ``data`` so that a kill at any instant leaves the old file or the
    new one, whole: written to a temporary file in the same directory, fsynced, renamed over
    ``path``, and the directory fsynced so the rename itself survives a crash.

    With ``previous``, the current ``path`` is first renamed to ``previous`` (the last good
    copy, kept until the next write): between the two renames ``path`` is missing and
    ``previous`` holds it. The file gets the permissions of a file opened the usual way
    (0666 less the umask), not mkstemp's private 0600, so colleagues read every file of a
    run alike. An OSError (disk full, ...) removes the temporary file, ``path`` unchanged."""
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
    checkpoint stays intact."""
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
        atomic_write(target, buffer.getvalue())
        target = run_dir / STATE_NPZ
        atomic_write(target, _npz_bytes(arrays), previous=run_dir / STATE_PREV)
    except OSError as exc:
        reason = f"{exc.strerror or exc}; {intact_checkpoint(run_dir)}"
        raise RunError(f"cannot write the checkpoint of generation {generation}: {target}: "
                       f"{reason}") from None  # fmt: skip
    try:
        atomic_write(run_dir / STATE_JSON, meta_text)
    except OSError as exc:
        raise RunError(f"{run_dir / STATE_JSON}: {exc.strerror or exc}; the checkpoint of "
                       f"generation {generation} is saved in {STATE_NPZ}") from None  # fmt: skip


def intact_checkpoint(run_dir: Path) -> str:
    """What a failed write leaves to resume from, for its error: the generation state.npz
    holds now (the new one, where only the directory's fsync failed)."""
    try:
        with np.load(run_dir / STATE_NPZ) as data:
            return f"the checkpoint of generation {int(data['generation'])} is intact"
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return "there is no earlier checkpoint"


def record_provenance(run_dir: Path, done: int, total: int) -> None:
    """Append this process's segment (generations ``done`` to ``total``) to provenance.json
    (:func:`~physrover.experiment.provenance.with_segment`, which warns of other code or
    another CPU); none when ``done >= total`` (a finished run resumed trains nothing)."""
    if done < total:
        segments = with_segment(run_dir, done)
        text = json.dumps({"segments": segments}, indent=1) + "\n"
        atomic_write(run_dir / PROVENANCE, text)


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
    :func:`atomic_write`) or cannot be read, ``state.prev.npz`` is, with a warning when
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
        stale.unlink()  # a temporary file of atomic_write that a kill left behind
    meta = load_state(out, learner)
    done = 0 if meta is None else int(meta["generation"])
    rows = [r for r in read_metrics(out / METRICS) if r["generation"] <= done] if meta else []
    write_metrics(out / METRICS, rows, header)
    for generation, path in champion_checkpoints(out).items():
        if generation > done:
            path.unlink()
    if meta is not None and last_checkpoint(out) != done:
        atomic_write(out / STATE_JSON, json.dumps(meta))
    return rows


def last_checkpoint(run_dir: Path) -> int | None:
    """Generations completed at the run's latest checkpoint, or None if it has none."""
    try:
        return int(json.loads((Path(run_dir) / STATE_JSON).read_text())["generation"])
    except (OSError, ValueError, KeyError):
        return None


def write_metrics(path: Path, rows: list[dict], header: list[str] | None = None) -> None:
    """metrics.csv at ``path``: ``header`` (default the CCEA's) and ``rows``, atomically."""
    atomic_write(path, metrics_text(rows, header or stats_header()))


def prepare_run_dir(out: Path, config: RunConfig, header: list[str] | None = None) -> None:
    """A new run: its config and an empty metrics.csv (where :func:`check_new` allows)."""
    check_new(out)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / CONFIG, config.to_toml())
    write_metrics(out / METRICS, [], header)


def check_new(out: Path) -> None:
    """Refuse ``out`` for a new run unless it is missing or holds nothing but a claim."""
    if out.exists() and (not out.is_dir() or any(p.name != CLAIM for p in out.iterdir())):
        raise RunError(f"{out} exists and is not empty; use --resume {out} to continue it")


def find_runs(paths: list[str | Path]) -> list[Path]:
    """Run directories named in ``paths``, or found below them (e.g. a sweep's root). A
    file among them is passed over (a shell glob such as ``runs/sweeps/smoke/*`` also
    matches the ``curves.csv`` an earlier call wrote there); a path that does not exist is
    an error."""
    found: list[Path] = []
    for path in map(Path, paths):
        if (path / CONFIG).is_file():
            found.append(path)
        elif path.is_dir():
            found.extend(sorted(p.parent for p in path.rglob(CONFIG)))
        elif not path.exists():
            raise RunError(f"{path} does not exist")
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
