"""Progress of long loops on stderr, drawn by tqdm.

On a terminal: one live tqdm bar (done/total, the given fields, rate, time left). Not on a
terminal (a log file, a CI job, a sweep worker): a line every 10% and at the end, in the same
tqdm format, instead of a bar redrawn with carriage returns.

``warm_up(text)`` shows a status while something that should not count towards the rate runs
(compiling the kernels on a first run): the rate and the time left count only what follows.
"""

from __future__ import annotations

import sys
import time

from tqdm import tqdm


class Progress:
    """``Progress(total, label, start=done_already, unit="gen")``; ``update(done, **fields)``;
    ``close()``."""

    def __init__(self, total: int, label: str = "", start: int = 0, stream=None, unit="it"):
        self.total, self.label, self.unit = total, label, unit
        self.stream = stream or sys.stderr
        self.tty = getattr(self.stream, "isatty", lambda: False)()
        self.bar = None
        self.restart_clock(start)

    def _new_bar(self, done: int, desc: str) -> None:
        if self.bar is not None:
            self.bar.close()
        self.bar = tqdm(total=self.total, initial=done, desc=desc, file=self.stream,
                        unit=self.unit, dynamic_ncols=True, smoothing=0.1, leave=True)  # fmt: skip

    def warm_up(self, text: str) -> None:
        """Show ``text`` until the next ``restart_clock``; that time is left out of the rate."""
        if self.tty:
            self._new_bar(self.start, f"{self.label} ({text})")
        else:
            self.stream.write(f"{self.label}: {text}\n")
            self.stream.flush()

    def restart_clock(self, done: int) -> None:
        """Measure the rate and time left from now, with ``done`` steps already behind."""
        self.start, self.t0 = done, time.perf_counter()
        self.last_decile = int(10 * done / max(self.total, 1))
        if self.tty:
            self._new_bar(done, self.label)

    def update(self, done: int, **fields: float | str) -> None:
        postfix = {k: (f"{v:.2f}" if isinstance(v, float) else str(v)) for k, v in fields.items()}
        if self.bar is not None:
            self.bar.set_postfix(postfix, refresh=False)
            self.bar.update(done - self.bar.n)
            return
        decile = int(10 * done / max(self.total, 1))
        if decile == self.last_decile and done < self.total:
            return
        self.last_decile = decile
        elapsed = time.perf_counter() - self.t0
        rate = (done - self.start) / elapsed if elapsed > 0 and done > self.start else None
        line = tqdm.format_meter(
            done, self.total, elapsed, prefix=self.label, unit=self.unit, rate=rate,
            postfix=", ".join(f"{k}={v}" for k, v in postfix.items()), initial=self.start,
        )  # fmt: skip
        self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
