"""A one-line progress display for long loops (stderr; quiet when not a terminal)."""

from __future__ import annotations

import sys
import time


def _clock(seconds: float) -> str:
    seconds = int(max(seconds, 0))
    hours, rest = divmod(seconds, 3600)
    return f"{hours}:{rest // 60:02d}:{rest % 60:02d}" if hours else f"{rest // 60}:{rest % 60:02d}"


class Progress:
    """``Progress(total, label)``; call ``update(done, **fields)`` and ``close()``.

    Redraws at most ``hz`` times a second; shows done/total, a bar, the given fields, the rate
    and the time left. When stderr is not a terminal, prints a line every 10% instead.
    """

    def __init__(self, total: int, label: str = "", start: int = 0, hz: float = 4.0, stream=None):
        self.total, self.label, self.start = total, label, start
        self.stream = stream or sys.stderr
        self.tty = getattr(self.stream, "isatty", lambda: False)()
        self.t0 = time.perf_counter()
        self.last_draw, self.last_decile = 0.0, -1
        self.min_interval = 1.0 / hz

    def update(self, done: int, **fields: float | str) -> None:
        now = time.perf_counter()
        decile = int(10 * done / max(self.total, 1))
        final = done >= self.total
        if self.tty and not final and now - self.last_draw < self.min_interval:
            return
        if not self.tty and not final and decile == self.last_decile:
            return
        self.last_draw, self.last_decile = now, decile
        rate = (done - self.start) / max(now - self.t0, 1e-9)
        eta = (self.total - done) / rate if rate > 0 else float("inf")
        width = 24
        filled = int(width * done / max(self.total, 1))
        bar = "#" * filled + "-" * (width - filled)
        extra = " ".join(
            f"{k} {v:.2f}" if isinstance(v, float) else f"{k} {v}" for k, v in fields.items()
        )
        eta_text = _clock(eta) if eta != float("inf") else "?"
        line = f"{self.label} {done}/{self.total} [{bar}] {extra} | {rate:.1f}/s | ETA {eta_text}"
        if self.tty:
            self.stream.write("\r" + line[:160].ljust(120))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()
