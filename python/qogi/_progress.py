"""A small text progress bar for the command line (stderr, throttled)."""

from __future__ import annotations

import sys
import time
from typing import Optional, TextIO

from ._interrupts import pending


class ProgressBar:
    """``bar(fraction, message)`` draws ``[#####.....]  42%  message`` on stderr.

    On a terminal it redraws one line; otherwise it prints a line at most every
    ``interval_s`` seconds (and at 100 %), so logs stay readable. A callback of
    qogi's progress protocol (:mod:`qogi.progress`), usable as the ``progress``
    of its long-running functions; it cancels (returns False) only when a
    Ctrl-C was dropped by Python (:mod:`qogi._interrupts`), otherwise Ctrl-C
    itself stops the run.
    """

    def __init__(
        self,
        label: str = "",
        width: int = 30,
        stream: Optional[TextIO] = None,
        interval_s: Optional[float] = None,
        enabled: bool = True,
    ):
        self.label = label
        self.width = width
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.interval_s = interval_s if interval_s is not None else (0.1 if self.tty else 5.0)
        self.enabled = enabled
        self._last = 0.0
        self._t0 = time.perf_counter()
        self._done = False

    def __call__(self, fraction: float, message: str = "") -> Optional[bool]:
        if pending() is not None:
            return False
        if not self.enabled or self._done:
            return None
        now = time.perf_counter()
        final = fraction >= 1.0
        if not final and now - self._last < self.interval_s:
            return None
        self._last = now
        f = min(max(float(fraction), 0.0), 1.0)
        n = int(round(f * self.width))
        elapsed = now - self._t0
        eta = f"  eta {elapsed / f - elapsed:5.0f} s" if 0.02 < f < 1.0 else ""
        line = (
            f"{self.label}[{'#' * n}{'.' * (self.width - n)}] {100 * f:5.1f}%  "
            f"{elapsed:6.1f} s{eta}  {message}"
        )
        if self.tty:
            self.stream.write("\r" + line[:160].ljust(100))
            if final:
                self.stream.write("\n")
                self._done = True
        else:
            self.stream.write(line + "\n")
            self._done = final
        self.stream.flush()
        return None

    def close(self) -> None:
        if self.enabled and not self._done and self.tty:
            self.stream.write("\n")
            self.stream.flush()
        self._done = True
