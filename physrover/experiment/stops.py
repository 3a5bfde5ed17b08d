"""Stops: a Ctrl-C or SIGTERM (a cluster's time limit) asks a run to end its generation,
checkpoint it and stop, instead of interrupting it; a second Ctrl-C interrupts at once
(never in the middle of a checkpoint). In a sweep's worker the request comes from the
sweep's process instead (:func:`set_stop_event`).
"""

from __future__ import annotations

import contextlib
import signal
import threading

_stop_event = None
"""A sweep worker's stop: an event its pool sets when the sweep is interrupted
(:func:`set_stop_event`); None in a process of its own."""


def set_stop_event(event) -> None:
    """Make ``event`` (``is_set()``) this process's stop request instead of its own signals:
    what a sweep's pool workers do (:mod:`physrover.experiment.execute`), which then leave
    the signals to the sweep's process."""
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
