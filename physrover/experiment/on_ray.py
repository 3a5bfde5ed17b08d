"""Sweeps on Ray: the runs as Ray tasks, on a cluster (``--ray HOST:PORT``) or a Ray started
here on loopback (``--ray local``).

- A run whose node dies is run again by Ray (up to :data:`RAY_RETRIES` times) on a node
  that is alive, where it resumes from its last checkpoint: every node must see the run
  root at the same path.
- The head node lost (its GCS stops answering for :data:`HEAD_LOST_AFTER` seconds): the
  driver ends at once with one line (:class:`ClusterLost`) instead of Ray's minute of
  retries and its own abort. Every run keeps its last checkpoint and its claim is released
  with the process that held it (:mod:`physrover.experiment.claims`), so the same command
  on a new head resumes the sweep: finished runs are skipped, the others resume, none is
  trained twice at once.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import sys
import threading
import time
from typing import Any
from urllib.parse import urlsplit

from physrover.config import ConfigError
from physrover.core import plugins

RAY_RETRIES = 3
"""How often Ray runs a run again whose node or worker process died (each attempt resumes
the run from its last checkpoint, on the shared run root)."""


HEAD_LOST_AFTER = 3.0
"""Seconds without an answer from the head's GCS after which a sweep's driver gives up on
the cluster (Ray itself waits 60 s, then aborts the process)."""


class ClusterLost(RuntimeError):
    """The Ray cluster's head stopped answering mid-sweep. The CLI prints it as one line and
    exits at once: Ray's own shutdown would wait for the lost head."""


def run_on_ray(todo, address, record, bar, skipped, workers, task) -> None:
    """The runs ``todo`` as Ray tasks of ``task`` (``run_one``), one CPU each; ``record``
    takes each result, ``bar`` shows progress. A run Ray gives up on is reported as failed
    and the others go on; a lost head raises :class:`ClusterLost`."""
    with _ray_on_loopback() if address == "local" else contextlib.nullcontext():
        _run_ray_tasks(todo, address, record, bar, skipped, workers, task)


def _run_ray_tasks(todo, address, record, bar, skipped, workers, run_one) -> None:
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
    lost = False
    try:
        head = HeadWatch(ray.get_runtime_context().gcs_address)
        task = ray.remote(num_cpus=1, max_retries=RAY_RETRIES, retry_exceptions=False)(run_one)
        names = {task.remote(spec): spec.name for spec in todo}
        pending = list(names)
        while pending:
            if bar:
                bar.update(skipped + len(todo) - len(pending),
                           running=str(min(workers, len(pending))), failed="0")  # fmt: skip
            if head.lost():
                lost = True
                raise ClusterLost(
                    f"--ray: lost the Ray cluster at {address}: its head ({head.address}) has "
                    f"not answered for {HEAD_LOST_AFTER:.0f} s, with {len(todo) - len(pending)} "
                    f"of {len(todo)} runs finished; each run keeps its last checkpoint: start "
                    "a head again (and its nodes) and run the same command to resume"
                )
            done, pending = ray.wait(pending, num_returns=1, timeout=1.0)
            for ref in done:
                try:
                    record(ray.get(ref))
                except ray.exceptions.RayError as error:  # its node died too often
                    lines = str(error).strip().splitlines()
                    record((names[ref], 0.0, lines[0] if lines else type(error).__name__))
    finally:
        if started_here and not lost:
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


class HeadWatch:
    """Whether the head's GCS at ``address`` (``host:port``) still accepts connections,
    asked at most once a second; lost once it has not for :data:`HEAD_LOST_AFTER` s."""

    def __init__(self, address: str | None):
        self.address = address or ""
        self.silent_since: float | None = None
        self.asked = 0.0

    def lost(self) -> bool:
        now = time.monotonic()
        if not self.address or now - self.asked < 1.0:
            return False
        self.asked = now
        try:
            _connect(self.address, timeout=1.0)
            self.silent_since = None
        except (OSError, ValueError):
            self.silent_since = self.silent_since or now
        return self.silent_since is not None and now - self.silent_since >= HEAD_LOST_AFTER


def _connect(address: str, timeout: float) -> None:
    """Open and close a TCP connection to ``address`` (``host:port`` or
    ``scheme://host:port``); OSError if nothing accepts it in ``timeout`` s, ValueError for
    an address without a host and port."""
    target = urlsplit(address if "://" in address else f"tcp://{address}")
    host, port = target.hostname, target.port  # ValueError for a port that is no number
    if not host or port is None:
        raise ValueError(f"no host and port in {address!r}")
    socket.create_connection((host, port), timeout=timeout).close()


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Fail at once, naming ``address``, when nothing listens there (Ray itself retries for
    minutes). ``address``: ``host:port`` or ``ray://host:port``; others are left to Ray."""
    target = urlsplit(address if "://" in address else f"tcp://{address}")
    try:
        target.port  # noqa: B018 - raises ValueError for a port that is no number
    except ValueError:
        raise ConfigError("--ray", f"bad address {address!r} (expected HOST:PORT)") from None
    if not target.hostname or target.port is None:
        return
    try:
        _connect(address, timeout)
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
