"""Claims on run directories: a run is trained by one process at a time.

Before a process trains or resumes a run (``physrover train``, a sweep's worker on this
machine or on a Ray node), it claims the run directory: an exclusive ``flock`` on the file
``.claim`` in it, held until the run ends, with the holder's host, pid and start time
written into the file for whoever finds it taken. A second process is refused at once
(:class:`RunHeld`, one line naming the holder); a sweep's driver moves on to other runs and
comes back to it (:mod:`physrover.experiment.execute`), so any number of drivers share a
sweep, each run trained once.

What the lock guarantees, and its limits:

- The kernel releases the lock when its holder dies, however it dies (SIGKILL, an OOM
  kill): a claim never outlives its process on a local disk, and needs no heartbeat. A
  run whose holder died resumes from its last checkpoint in whoever claims it next.
- On NFS, Linux's ``flock`` is a lock of the whole file on the server (NFSv4, or NFSv3
  with the lock manager, ``lockd``), shared by every client; a client that loses the
  server keeps the lock until the server's lease expires (NFSv4: 90 s by default), so a
  crashed node's runs are taken over after that lease, not at once.
- On a filesystem whose locks are not shared between machines (NFS mounted ``nolock``, some
  FUSE and object-store mounts) every process gets the lock: claims then hold only between
  the processes of one machine. ``docs/user-guide/clusters.md`` says how to check.
- Within one process a claim is re-entrant (a sweep's worker claims a run, then trains it
  through ``train``, which claims it again). The file is never deleted (deleting a locked
  file would let a second process lock a new one of the same name).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import socket
import time
from collections.abc import Iterator
from pathlib import Path

from physrover.experiment.store import CLAIM, RunError

TRIES = 5
"""Attempts, 20 ms apart, before a claim is refused: another process's :func:`holder`
holds the file's lock shared for an instant."""

_held: dict[str, tuple[int, int, dict]] = {}
"""The claims this process holds: run directory -> (file descriptor, depth, holder). Its
own claim is never opened a second time: on NFS, where flock is a POSIX lock, closing any
descriptor of the file would release it."""


class HeldRun(str):
    """A sweep worker's answer for a run another process holds: the holder's line
    (:func:`holder_line`), not an error of the run."""


class RunHeld(RunError):
    """The run directory is claimed by another process; the message names it."""


def _key(run_dir: Path) -> str:
    return str(Path(run_dir).resolve())


def holder(run_dir: Path) -> dict | None:
    """Who holds the claim on ``run_dir`` (``{"host", "pid", "since"}``: since in seconds
    since the epoch), or None if no process does. This process's own claim included."""
    key = _key(run_dir)
    path = Path(run_dir) / CLAIM
    if key in _held:
        return dict(_held[key][2])
    try:  # another process's claim, or none
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError as exc:
        if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
            raise
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)
    try:
        who = json.loads(path.read_text() or "null")
    except (OSError, ValueError):
        who = None
    # locked but not yet (or no longer) named: held, by a process this cannot name
    return who if isinstance(who, dict) else {"host": "?", "pid": "?", "since": None}


def holder_line(run_dir: Path, who: dict) -> str:
    """``RUN is held by pid PID on HOST since TIME``."""
    if who.get("since") is None:
        return f"{run_dir} is held by another process (naming itself this instant)"
    since = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(who["since"]))
    return f"{run_dir} is held by pid {who.get('pid')} on {who.get('host')} since {since}"


def check_free(run_dir: Path) -> None:
    """Raise :class:`RunHeld` if another process holds ``run_dir`` now (a look before a
    message; :func:`claim` is what guarantees)."""
    who = None if _key(run_dir) in _held else holder(run_dir)
    if who is not None:
        raise RunHeld(_held_message(run_dir, who))


def _held_message(run_dir: Path, who: dict) -> str:
    return f"{holder_line(run_dir, who)}; it is trained there (stop that process to take it over)"


@contextlib.contextmanager
def claim(run_dir: Path) -> Iterator[None]:
    """Hold ``run_dir``'s claim for the block (module docstring), creating the directory
    if need be; raises :class:`RunHeld` at once if another process holds it."""
    run_dir = Path(run_dir)
    key = _key(run_dir)
    if key in _held:  # re-entrant within a process
        fd, depth, me = _held[key]
        _held[key] = (fd, depth + 1, me)
        try:
            yield
        finally:
            fd, depth, me = _held[key]
            _held[key] = (fd, depth - 1, me)
        return
    if run_dir.exists() and not run_dir.is_dir():
        raise RunError(f"{run_dir} is a file, not a run directory")
    run_dir.mkdir(parents=True, exist_ok=True)
    fd = os.open(run_dir / CLAIM, os.O_RDWR | os.O_CREAT, 0o666)  # as the umask says
    for attempt in range(TRIES):
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            break
        except OSError as exc:
            if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                os.close(fd)
                raise
            # another process's look (holder()) holds a shared lock for an instant
            if attempt == TRIES - 1:
                os.close(fd)
                raise RunHeld(_held_message(run_dir, holder(run_dir) or {})) from None
            time.sleep(0.02)
    try:
        me = {"host": socket.gethostname(), "pid": os.getpid(), "since": time.time()}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(me).encode(), 0)
        _held[key] = (fd, 1, me)
        yield
    finally:
        _held.pop(key, None)
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)  # no holder to name once released
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def clear_run_dir(out: Path) -> None:
    """Empty a run directory that died before its config was written, keeping its claim
    (deleting a claimed file would let another process claim a new one)."""
    for path in Path(out).iterdir():
        if path.name == CLAIM:
            continue
        shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()


__all__ = [
    "CLAIM",
    "clear_run_dir",
    "HeldRun",
    "RunHeld",
    "check_free",
    "claim",
    "holder",
    "holder_line",
]
