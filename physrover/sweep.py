"""Sweeps: grids of training runs on a local process pool or on a Ray cluster.

A sweep file (TOML) names a base config and a grid::

    [sweep]
    name = "fig4-7"          # runs go under ROOT/name/ (ROOT: --root, default runs/sweeps)
    seeds = 5                # seeds 0 .. seeds-1 for every cell (--seeds N or A:B overrides)
    imports = ["my_parts.py"]  # optional: your own parts the grid names (physrover.plugins)

    [base.domain]            # the base RunConfig, as in a run's config.toml
    n_rovers = 15
    [base.learn]
    generations = 1000

    [grid]                   # any config field -> the values to try
    method = ["D", "average", "mean-critic", "max-critic"]
    n_req = [3, 4, 5, 6]

    [[variants]]             # optional: combinations that are not a product, each crossed
    motion = "ideal"         # with the grid (here: idealised, and physics without and
    [[variants]]             # with collisions; "ideal with collisions" would be a copy)
    motion = "physics"
    collisions = false

Every cell x seed is one ``train`` run in its own directory, named by its grid values and
seed. Re-running a sweep skips finished runs and resumes interrupted ones from their
checkpoints; a crashed run is reported with its error and does not stop the others. Each
worker runs one training at a time with torch/BLAS pinned to one thread.

``--seeds A:B`` runs seeds A .. B-1 only: a sweep too long for one machine's lifetime can be
run in chunks of seeds (e.g. ``--seeds 0:5`` then ``--seeds 5:10``), each run's name and
results being those it has in the whole sweep. ``--skip-listed CSV`` leaves out the runs a
results table (``experiments/results/runs.csv``: columns sweep, run, generations) lists as
finished, so a later machine runs only what no earlier one finished (:func:`listed_finished`).
"""

from __future__ import annotations

import contextlib
import itertools
import multiprocessing
import os
import shutil
import signal
import sys
import threading
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from physrover import plugins
from physrover.config import ConfigError, RunConfig, load_toml_file, naming_file
from physrover.progress import Progress
from physrover.runs import drop_state
from physrover.threads import pin_threads


@dataclass(frozen=True)
class RunSpec:
    name: str
    config_toml: str
    out: str
    drop_state: bool = False
    """Delete the run's checkpoint (state.npz, state.prev.npz) when it finishes (see
    :func:`physrover.runs.drop_state`)."""


@dataclass(frozen=True)
class Sweep:
    name: str
    base: RunConfig
    grid: dict[str, list[Any]]
    seeds: int
    variants: tuple[dict[str, Any], ...] = ({},)
    imports: tuple[str, ...] = ()
    """[sweep] imports: modules or .py files (relative to the sweep file) of the researcher's
    own parts that the runs name, imported when the file is loaded and by every worker
    (:mod:`physrover.plugins`)."""

    @classmethod
    def load(cls, path: str | Path) -> Sweep:
        """The sweep in a TOML file; every error names the file."""
        data = load_toml_file(path)
        with naming_file(path):
            return cls._from_dict(data, path)

    @classmethod
    def _from_dict(cls, data: dict, path: str | Path) -> Sweep:
        unknown = sorted(set(data) - {"sweep", "base", "grid", "variants"})
        if unknown:
            raise ConfigError(
                unknown[0], "unknown sweep table (known: sweep, base, grid, variants)"
            )
        meta = data.get("sweep", {})
        bad = sorted(set(meta) - {"name", "seeds", "imports"})
        if bad:
            raise ConfigError(bad[0], "unknown [sweep] key (known: name, seeds, imports)")
        imports = meta.get("imports", [])
        if not isinstance(imports, list) or not all(isinstance(i, str) for i in imports):
            raise ConfigError("imports", "must be a list of module names or .py paths")
        plugins.load(imports, base=Path(path).resolve().parent)  # before any name is checked
        base = RunConfig.from_dict(data.get("base", {}))
        grid = data.get("grid", {})
        for field, values in grid.items():
            if not isinstance(values, list) or not values:
                raise ConfigError(field, "grid values must be a non-empty list")
            base.with_overrides({field: values[0]})  # the name must be a config field
        seeds = meta.get("seeds", 1)
        if not isinstance(seeds, int) or seeds < 1:
            raise ConfigError("seeds", f"must be a positive integer, got {seeds!r}")
        variants = tuple(data.get("variants", [{}]))
        for variant in variants:
            base.with_overrides(variant)  # names and values must be valid
        name = str(meta.get("name", Path(path).stem))
        return cls(name, base, grid, seeds, variants, tuple(imports))

    def runs(
        self, root: str | Path, seeds: int | range | None = None, drop_state: bool = False
    ) -> list[RunSpec]:
        """Every cell x seed, with its resolved config; invalid cells are config errors.
        In the order they run: every cell's first seed, then every cell's second, ... (so a
        sweep stopped part-way has its finished seeds spread evenly over the cells).
        ``seeds``: how many (seeds 0 .. seeds-1) or which (a range); default the file's.
        ``drop_state``: each run deletes its checkpoint when it finishes."""
        fields = list(self.grid)
        specs = []
        cells = list(
            itertools.product(itertools.product(*(self.grid[f] for f in fields)), self.variants)
        )
        chosen = seeds if isinstance(seeds, range) else range(seeds or self.seeds)
        for seed in chosen:  # seed-major: a sweep stopped part-way leaves every cell its seeds
            for values, variant in cells:
                overrides = {**dict(zip(fields, values, strict=True)), **variant, "seed": seed}
                config = self.base.with_overrides(overrides)
                name = "_".join(f"{f}={_slug(v)}" for f, v in overrides.items())
                out = str(Path(root) / self.name / name)
                specs.append(RunSpec(name, config.to_toml(), out, drop_state))
        return specs


def parse_seeds(text: str) -> int | range:
    """``--seeds``: ``N`` (seeds 0 .. N-1) or ``A:B`` (seeds A .. B-1), N >= 1, 0 <= A < B."""
    try:
        if ":" in text:
            first, stop = (int(part) for part in text.split(":"))
            if 0 <= first < stop:
                return range(first, stop)
        elif int(text) >= 1:
            return int(text)
    except ValueError:
        pass
    raise ConfigError(
        "seeds", f"must be N >= 1 (seeds 0..N-1) or A:B with 0 <= A < B, got {text!r}"
    )


def listed_finished(specs: list[RunSpec], table: str | Path, sweep: str) -> set[str]:
    """The names of the ``specs`` that the CSV ``table`` (columns ``sweep``, ``run``,
    ``generations``) lists under ``sweep`` with at least the generations their config asks
    for: runs an earlier machine finished."""
    import csv

    path = Path(table)
    if not path.is_file():
        raise ConfigError("skip-listed", f"{path} is not a file")
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = {"sweep", "run", "generations"} - set(reader.fieldnames or ())
        if missing:
            raise ConfigError("skip-listed", f"{path} has no column {sorted(missing)[0]!r}")
        done = {row["run"]: int(row["generations"]) for row in reader if row["sweep"] == sweep}
    return {
        spec.name
        for spec in specs
        if spec.name in done and done[spec.name] >= RunConfig.from_toml(spec.config_toml).length
    }


def _slug(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return "-".join(_slug(v) for v in value)
    return str(value).lower() if isinstance(value, bool) else str(value)


def run_status(spec: RunSpec) -> str:
    """ "done", "partial" (has a checkpoint or a started directory) or "new"."""
    return run_progress(spec)[0]


def run_progress(spec: RunSpec) -> tuple[str, int, int]:
    """(:func:`run_status`, the generation of the run's last checkpoint (0 without one),
    the run's length): a resume starts from that checkpoint, so a run that is training
    now is reported as far as it has checkpointed."""
    import json

    out = Path(spec.out)
    length = RunConfig.from_toml(spec.config_toml).length
    if not out.exists():
        return "new", 0, length
    state = out / "state.json"
    if not state.exists():
        return "partial", 0, length
    generation = int(json.loads(state.read_text())["generation"])
    return ("done" if generation >= length else "partial"), generation, length


def status_report(name: str, specs: list[RunSpec], listed: int = 0) -> list[str]:
    """``physrover sweep FILE --status``: a line per run that is not done (its status and
    checkpointed generations of its length, then its directory), and a last line counting
    done, partial and new runs, the share of their generations that is checkpointed, and
    the ``listed`` runs that ``--skip-listed`` left out."""
    counts = {"done": 0, "partial": 0, "new": 0}
    lines, reached, total = [], 0, 0
    for spec in specs:
        status, generation, length = run_progress(spec)
        counts[status] += 1
        reached, total = reached + min(generation, length), total + length
        if status != "done":
            lines.append(f"{status:7s} {generation:>7d}/{length:<7d} {spec.out}")
    share = 100.0 * reached / total if total else 100.0
    summary = ", ".join(f"{n} {s}" for s, n in counts.items())
    summary += f"; {share:.1f}% of their generations checkpointed"
    if listed:
        summary += f"; {listed} more listed as finished by --skip-listed"
    lines.append(f"sweep {name}: {summary}")
    return lines


def run_one(spec: RunSpec) -> tuple[str, float, str | None]:
    """Train (or resume) one run; returns (name, seconds, error or None). A run's error is
    returned, not raised; a stop of the sweep (:func:`_run_pool`) raises KeyboardInterrupt,
    before the run starts if it came first."""
    from physrover import runs

    if runs._stop_event is not None and runs._stop_event.is_set():
        raise KeyboardInterrupt(f"{spec.name}: not started, the sweep is stopping")
    start = time.perf_counter()
    try:
        pin_threads(1)
        plugins.load_from_environment()  # a spawned or Ray worker: the parts the runs name
        from physrover.runs import train

        status = run_status(spec)
        if status != "done":
            config = RunConfig.from_toml(spec.config_toml)
            out = Path(spec.out)
            if status == "partial":
                if not (out / "config.toml").exists():  # died before writing anything useful
                    shutil.rmtree(out)
                    train(config, out, progress=False)
                else:
                    train(None, out, resume=True, generations=config.learn.generations,
                          progress=False)  # fmt: skip
            else:
                train(config, out, progress=False)
        if spec.drop_state:
            drop_state(Path(spec.out))
        return spec.name, time.perf_counter() - start, None
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

    def record(result: tuple[str, float, str | None]) -> None:
        name, _, error = result
        if error is None:
            finished.append(name)
        else:
            failed[name] = error
            print(f"\nrun failed: {name}: {error}", file=sys.stderr)

    workers = workers or max(1, (os.cpu_count() or 1))
    if todo and ray_address:
        _run_ray(todo, ray_address, record, bar, skipped, workers)
    elif todo:
        _run_pool(todo, workers, record, bar, skipped, finished, failed)
    _display(bar, len(specs), 0, len(failed))
    if bar:
        bar.close()
    return SweepReport(len(specs), skipped, finished, failed, time.perf_counter() - start)


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
    sweep's event (:func:`physrover.runs.set_stop_event`)."""
    from physrover.runs import set_stop_event

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


RAY_RETRIES = 3
"""How often Ray runs a run again whose node or worker process died (each attempt resumes
the run from its last checkpoint, on the shared run root)."""


def _run_ray(todo, address, record, bar, skipped, workers) -> None:
    """The runs as Ray tasks, one CPU each. A task whose node dies is run again by Ray (up
    to :data:`RAY_RETRIES` times) on a node that is alive, where :func:`run_one` resumes it
    from its last checkpoint: every node must see the run root at the same path. A run Ray
    gives up on is reported as failed and the others go on."""
    with _ray_on_loopback() if address == "local" else contextlib.nullcontext():
        _run_ray_tasks(todo, address, record, bar, skipped, workers)


def _run_ray_tasks(todo, address, record, bar, skipped, workers) -> None:
    try:
        import ray
    except ImportError:
        raise ConfigError("--ray", "ray is not installed: pip install 'physrover[ray]'") from None
    started_here = not ray.is_initialized()
    main_thread = threading.current_thread() is threading.main_thread()
    handlers = (
        {n: signal.getsignal(n) for n in (signal.SIGINT, signal.SIGTERM)} if main_thread else {}
    )
    if started_here:
        _connect_ray(ray, address, workers)
    try:
        task = ray.remote(num_cpus=1, max_retries=RAY_RETRIES, retry_exceptions=False)(run_one)
        names = {task.remote(spec): spec.name for spec in todo}
        pending = list(names)
        while pending:
            _display(bar, skipped + len(todo) - len(pending), min(workers, len(pending)), 0)
            done, pending = ray.wait(pending, num_returns=1, timeout=1.0)
            for ref in done:
                try:
                    record(ray.get(ref))
                except ray.exceptions.RayError as error:  # its node died too often
                    lines = str(error).strip().splitlines()
                    record((names[ref], 0.0, lines[0] if lines else type(error).__name__))
    finally:
        if started_here:
            ray.shutdown()
        for number, handler in handlers.items():  # ray.init installs its own SIGTERM handler
            signal.signal(number, handler)


@contextlib.contextmanager
def _ray_on_loopback():
    """Inside, a Ray started here (``--ray local``) stays on 127.0.0.1: every server it
    starts (GCS, raylet, workers, runtime-env agent) binds the loopback address instead of
    all interfaces, so nothing of a sweep is reachable from the network.

    Ray does so when it is told the machine is not a cluster node: the environment variable
    ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0`` (Ray's own switch for laptops; its processes
    read it from the environment they inherit). A user's own value is respected. If ray was
    imported before, its driver read the variable already, so its constant is set too.
    Both are restored on exit.
    """
    name = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
    before = os.environ.get(name)
    os.environ.setdefault(name, "0")
    constants = sys.modules.get("ray._private.ray_constants")
    flag = getattr(constants, "ENABLE_RAY_CLUSTER", None)
    if constants is not None and os.environ[name] == "0":
        constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(name, None)
        if constants is not None:
            constants.ENABLE_RAY_CLUSTER = flag


RAY_HELP = (
    "start a cluster with `ray start --head` (it prints the address to pass) "
    "or run here with --ray local"
)


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Fail at once, naming ``address``, when nothing listens there (Ray itself retries for
    minutes). ``address``: ``host:port`` or ``ray://host:port``; others are left to Ray."""
    import socket
    from urllib.parse import urlsplit

    target = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        host, port = target.hostname, target.port
    except ValueError:
        raise ConfigError("--ray", f"bad address {address!r} (expected HOST:PORT)") from None
    if not host or port is None:
        return
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        reason = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise ConfigError(
            "--ray", f"no Ray cluster answers at {address} ({reason}); {RAY_HELP}"
        ) from None


def _connect_ray(ray, address: str, workers: int, timeout: int = 30) -> None:
    """``ray.init`` for ``address`` ("local" starts Ray here), failing within about
    ``timeout`` seconds with one line instead of hanging or a traceback.

    Ray must be initialised in the main thread, so the time limit is an alarm signal (on
    platforms that have one, when called from the main thread).
    """
    if address != "local":
        _check_reachable(address)
    kwargs: dict[str, Any] = {"num_cpus": workers} if address == "local" else {}
    if os.environ.get(plugins.ENV):  # the workers import the researcher's parts too
        kwargs["runtime_env"] = {"env_vars": {plugins.ENV: os.environ[plugins.ENV]}}
    alarm = (
        address != "local"
        and hasattr(signal, "SIGALRM")
        and threading.current_thread() is threading.main_thread()
    )

    def give_up(signum, frame):
        raise TimeoutError(f"no answer in {timeout} s")

    previous = signal.signal(signal.SIGALRM, give_up) if alarm else None
    if alarm:
        signal.alarm(timeout)
    try:
        ray.init(address=None if address == "local" else address, include_dashboard=False,
                 log_to_driver=False, logging_level="ERROR", **kwargs)  # fmt: skip
    except Exception as error:  # Ray raises many kinds; the user needs one line
        lines = str(error).strip().splitlines()
        reason = lines[0] if lines else type(error).__name__
        raise ConfigError(
            "--ray", f"cannot connect to Ray at {address}: {reason}; {RAY_HELP}"
        ) from None
    finally:
        if alarm:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, previous)
