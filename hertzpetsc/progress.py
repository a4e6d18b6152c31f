"""The progress of a long run with an estimate of the time left: one line now and then, on rank 0 only, and only when
stdout is a terminal (a log file, a pipe, a notebook or the test suite get the run's own output and nothing else).
The estimate assumes the work left goes at the pace of the work done so far (in the units the caller counts:
steps, records, time of a simulation), and says so.
"""
from __future__ import annotations

import sys
import time
from typing import Callable, Optional, TextIO

from petsc4py import PETSc

# seconds between two lines of a Progress (the first after this long too, so short runs print none)
INTERVAL = 30.0


def duration(seconds: float) -> str:
    """``seconds`` as '45 s', '12 min 5 s' or '2 h 13 min'."""
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    return f"{s // 3600} h {s % 3600 // 60} min"


class Progress:
    """Progress towards ``total`` (in the caller's units, named ``unit``) from ``start``: :meth:`update` with the
    amount done writes ``<label>: done/total unit, <elapsed> elapsed, about <left> left at the pace so far`` to
    ``stream`` (default stdout) at most every ``interval`` seconds, on rank 0 of ``comm``, when the stream is a
    terminal (``enabled`` forces it on or off)."""

    def __init__(self, total: float, unit: str = "steps", label: str = "progress", start: float = 0.0,
                 comm: Optional[PETSc.Comm] = None, interval: float = INTERVAL, stream: Optional[TextIO] = None,
                 enabled: Optional[bool] = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.total, self.unit, self.label, self.start = float(total), unit, label, float(start)
        self.stream = stream if stream is not None else sys.stdout
        rank0 = (comm if comm is not None else PETSc.COMM_WORLD).getRank() == 0
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = rank0 and enabled
        self.interval, self.clock = float(interval), clock
        self.t0 = self.last = clock()

    def left(self, done: float) -> Optional[float]:
        """Seconds left at the pace so far (None before any progress, or past the total)."""
        ran = done - self.start
        if not ran > 0 or done > self.total:            # (a start of nan: nothing known to pace by)
            return None
        return (self.clock() - self.t0) * (self.total - done) / ran

    def line(self, done: float) -> str:
        """The progress line at ``done``."""
        left = self.left(done)
        what = f"{done:g}/{self.total:g} {self.unit}" if done == int(done) and self.total == int(self.total) else \
            f"{done:.4g}/{self.total:.4g} {self.unit}"
        return (f"{self.label}: {what}, {duration(self.clock() - self.t0)} elapsed"
                + (f", about {duration(left)} left at the pace so far" if left is not None else ""))

    def update(self, done: float, force: bool = False) -> Optional[str]:
        """Write the line when enabled and ``interval`` seconds have passed since the last (or ``force``); returns
        what was written (None: nothing)."""
        if not self.enabled:
            return None
        now = self.clock()
        if not force and now - self.last < self.interval:
            return None
        self.last = now
        text = self.line(done)
        self.stream.write(text + "\n")
        self.stream.flush()
        return text
