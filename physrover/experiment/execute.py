"""Where a sweep's runs run: :func:`run_one` (one run, trained or resumed, in whichever
process or node it lands), :func:`run_sweep` (every run of a sweep that is not done) on a
local process pool or on Ray (``--ray local`` on loopback, or a cluster, where a run whose
node dies is run again elsewhere and resumes from its checkpoint). The sweep files and the
runs they name are :mod:`physrover.experiment.sweep`'s.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
import threading
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

from physrover.config import RunConfig
from physrover.core import plugins
from physrover.core.progress import Progress
from physrover.core.threads import pin_threads
from physrover.experiment.claims import HeldRun, RunHeld, claim, clear_run_dir, holder
from physrover.experiment.on_ray import run_on_ray
from physrover.experiment.store import drop_state
from physrover.experiment.sweep import RunSpec, run_status

HELD_POLL = 1.0
"""Seconds between a driver's looks at the runs other processes hold."""


class AlreadyDone(str):
    """:func:`run_one`'s answer for a run found finished once claimed (another driver of
    the sweep trained it since this one listed it): not an error."""


def run_one(spec: RunSpec) -> tuple[str, float, str | None]:
    """Train (or resume) one run; returns (name, seconds, error or None). A run's error is
    returned, not raised; a run another process holds (another driver of the sweep,
    :mod:`physrover.experiment.claims`) returns a :class:`HeldRun` naming it, untouched;
    a stop of the sweep (:func:`_run_pool`) raises KeyboardInterrupt, before the run starts
    if it came first."""
    from physrover.experiment import stops

    if stops._stop_event is not None and stops._stop_event.is_set():
        raise KeyboardInterrupt(f"{spec.name}: not started, the sweep is stopping")
    start = time.perf_counter()
    try:
        pin_threads(1)
        plugins.load_from_environment()  # a spawned or Ray worker: the parts the runs name
        from physrover.experiment.training import train

        out = Path(spec.out)
        with claim(out):  # the status is read under the claim: another driver may train it
            status = run_status(spec)
            if status == "done":  # finished by another driver since this one listed it
                result = AlreadyDone(spec.name)
            else:
                result = None
                config = RunConfig.from_toml(spec.config_toml)
                if not (out / "config.toml").exists():  # new, or died before writing it
                    clear_run_dir(out)
                    train(config, out, progress=False)
                else:
                    # up to the sweep's length, in the learner's unit (a trainer's runs
                    # count iterations)
                    length = {f"{config.unit}s": config.length}
                    train(None, out, resume=True, progress=False, **length)
            if spec.drop_state:
                drop_state(out)
        return spec.name, time.perf_counter() - start, result
    except RunHeld as held:
        return spec.name, time.perf_counter() - start, HeldRun(str(held))
    except Exception as exc:  # a crashed run is reported, the others go on
        detail = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        return spec.name, time.perf_counter() - start, detail


@dataclass
class SweepReport:
    total: int
    skipped: int
    finished: list[str]
    failed: dict[str, str]
    seconds: float


def _display(progress: Progress | None, done: int, running: int, failed: int) -> None:
    if progress:
        progress.update(done, running=str(running), failed=str(failed))


def run_sweep(
    specs: list[RunSpec],
    workers: int | None = None,
    ray_address: str | None = None,
    progress: bool = True,
) -> SweepReport:
    """Run every spec that is not finished; local process pool, or Ray tasks if an address
    is given ("local" starts a local Ray instance)."""
    start = time.perf_counter()
    todo = [s for s in specs if run_status(s) != "done"]
    skipped = len(specs) - len(todo)
    bar = Progress(len(specs), label="sweep runs", start=skipped, unit="run") if progress else None
    finished: list[str] = []
    failed: dict[str, str] = {}
    held: dict[str, str] = {}  # runs other processes hold: name -> who
    elsewhere: list[str] = []  # runs another driver finished meanwhile

    def record(result: tuple[str, float, str | None]) -> None:
        name, _, error = result
        if isinstance(error, HeldRun):
            held[name] = error
        elif isinstance(error, AlreadyDone):
            elsewhere.append(name)
        elif error is None:
            finished.append(name)
        else:
            failed[name] = error
            print(f"\nrun failed: {name}: {error}", file=sys.stderr)

    workers = workers or max(1, (os.cpu_count() or 1))
    by_name = {spec.name: spec for spec in todo}
    while todo:
        held.clear()
        if ray_address:
            run_on_ray(todo, ray_address, record, bar, skipped, workers, run_one)
        else:
            _run_pool(todo, workers, record, bar, skipped, finished, failed)
        todo = _released([by_name[name] for name in held], held)
    _display(bar, len(specs), 0, len(failed))
    if bar:
        bar.close()
    return SweepReport(len(specs), skipped + len(elsewhere), finished, failed,
                       time.perf_counter() - start)  # fmt: skip


def _released(waiting: list[RunSpec], held: dict[str, str]) -> list[RunSpec]:
    """``waiting``, the runs other processes held (``held`` names who), once one of them is
    released, whether its holder finished it or died (:mod:`physrover.experiment.claims`):
    a driver waits for the others, so every driver of a sweep ends when all its runs are
    done, and takes over the runs of a driver that died. Empty if none waits."""
    if not waiting:
        return []
    first = next(iter(held.values()))
    print(f"\nwaiting for {len(waiting)} run(s) other processes hold ({first})",
          file=sys.stderr)  # fmt: skip
    time.sleep(HELD_POLL)  # at least once: a holder finishing this instant is no hot loop
    while all(holder(Path(spec.out)) is not None for spec in waiting):
        time.sleep(HELD_POLL)
    return waiting


def _run_pool(todo, workers, record, bar, skipped, finished, failed) -> None:
    """The runs on a local process pool. Interrupted (Ctrl-C, or SIGTERM to this process or
    to a worker), each running run checkpoints the generation it is in and stops, no further
    run starts, and the KeyboardInterrupt goes on once they have; another Ctrl-C while they
    finish their generations stops them at once (SIGUSR1: each waits only for a checkpoint
    or metrics row it is writing). The workers leave SIGINT to this process and stop on its
    event (:func:`_worker_init`)."""
    workers = min(workers, len(todo))
    context = multiprocessing.get_context()
    stop = context.Event()
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context,
                               initializer=_worker_init, initargs=(stop,))  # fmt: skip
    queue, pending = list(todo), set()

    def fill() -> None:  # one run per worker in the pool at a time: none queued to cancel
        while queue and len(pending) < workers:
            pending.add(pool.submit(run_one, queue.pop(0)))

    try:
        with _sigterm_as(KeyboardInterrupt):
            fill()
            while pending:
                _display(bar, skipped + len(finished) + len(failed), len(pending), len(failed))
                done, pending = wait(pending, timeout=1.0, return_when=FIRST_COMPLETED)
                for future in done:
                    record(future.result())
                fill()
    except KeyboardInterrupt:
        stop.set()  # each running run ends its generation, checkpoints it and stops
        with _sigterm_as(None):  # a repeated SIGTERM is the same request
            try:
                pool.shutdown(wait=True, cancel_futures=True)
            except KeyboardInterrupt:  # another Ctrl-C: now
                for process in list(getattr(pool, "_processes", {}).values()):
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(process.pid, getattr(signal, "SIGUSR1", signal.SIGTERM))
                pool.shutdown(wait=True, cancel_futures=True)
        for future in pending:  # what finished or failed meanwhile is reported too
            if future.done() and not future.cancelled() and future.exception() is None:
                record(future.result())
        raise
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def _worker_init(stop) -> None:
    """A pool worker: Ctrl-C is the sweep's to handle (the terminal sends it to every
    process of the group), a SIGTERM here stops the whole sweep, and the runs stop on the
    sweep's event (:func:`physrover.experiment.stops.set_stop_event`)."""
    from physrover.experiment.stops import set_stop_event

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda signum, frame: stop.set())
    set_stop_event(stop)


@contextlib.contextmanager
def _sigterm_as(action):
    """Inside, SIGTERM raises ``action`` (KeyboardInterrupt, as a Ctrl-C does) or, with
    None, is ignored. Outside the main thread: nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        if action is not None:
            raise action

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)
