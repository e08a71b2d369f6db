"""Background work with progress and cancel, polled from the window's thread.

A :class:`Job` runs ``work(progress)`` in a daemon thread. ``progress(fraction,
message)`` records how far it is and returns ``False`` once :meth:`Job.cancel`
was called, which is exactly the progress-callback contract of
``qogi.quantify`` (returning ``False`` cancels). The window's thread only
reads the job's state (under a lock) and never blocks on it, so the window
stays responsive however long the work takes.
"""

from __future__ import annotations

import threading
import time
import traceback
from typing import Any, Callable, Optional

__all__ = ["Job", "Stopped", "RUNNING", "DONE", "CANCELLED", "FAILED"]

RUNNING, DONE, CANCELLED, FAILED = "running", "done", "cancelled", "failed"


class Stopped(Exception):
    """Raised by work that stops because its progress callback returned False."""


class Job:
    """One piece of background work.

    Parameters
    ----------
    name : str
        What it does, for people ("quantification", "demo scene").
    work : callable
        ``work(progress) -> value``; ``progress(fraction in [0, 1], message)``
        returns False when the job should stop. Raising an exception marks the
        job failed (its message is kept); ``cancelled_types`` marks it
        cancelled instead.
    cancelled_types : tuple of exception types
        Exceptions meaning "stopped on request" besides :class:`Stopped`
        and ``qogi.Cancelled`` (always);
        their ``.partial`` attribute, if any, is kept in :attr:`partial`.

    Attributes (read them through :meth:`snapshot` from another thread)
    ----------
    state : {"running", "done", "cancelled", "failed"}
    fraction, message : progress so far
    value : what ``work`` returned (state "done")
    error : the exception (state "failed" or "cancelled")
    partial : the ``.partial`` of a cancellation exception, or None
    traceback : formatted traceback of a failure ("" otherwise)
    """

    def __init__(
        self,
        name: str,
        work: Callable[[Callable[[float, str], bool]], Any],
        cancelled_types: tuple = (),
    ):
        self.name = name
        self._work = work
        from qogi.errors import Cancelled  # qogi's one cancellation type

        self._cancelled_types = (Stopped, Cancelled) + tuple(cancelled_types)
        self._lock = threading.Lock()
        self._cancel = threading.Event()
        self._ended = threading.Event()
        self.state = RUNNING
        self.fraction = 0.0
        self.message = "starting"
        self.value: Any = None
        self.error: Optional[BaseException] = None
        self.partial: Any = None
        self.traceback = ""
        self.started_s = time.monotonic()
        self.finished_s: Optional[float] = None
        # qogi's one helper for background work (owned daemon threads).
        from qogi.workers import Workers

        self._workers = Workers()

    def start(self) -> Job:
        self._workers.start(self._run, f"qogi-gui {self.name}")
        return self

    # ----------------------------------------------------------------- worker side
    def _progress(self, fraction, message="") -> bool:
        try:
            f = float(fraction)
        except (TypeError, ValueError):
            f = self.fraction
        with self._lock:
            if f == f:  # not NaN
                self.fraction = min(1.0, max(0.0, f))
            if message:
                self.message = str(message)
        return not self._cancel.is_set()

    def _run(self) -> None:
        try:
            value = self._work(self._progress)
        except self._cancelled_types as e:
            self._finish(CANCELLED, error=e, partial=getattr(e, "partial", None))
        except KeyboardInterrupt as e:  # Ctrl-C, or a loop that still stops this way
            if self._cancel.is_set():
                self._finish(CANCELLED, error=e)
            else:
                self._finish(FAILED, error=e, tb=traceback.format_exc())
        except Exception as e:  # noqa: BLE001 - any failure is reported in the window
            self._finish(FAILED, error=e, tb=traceback.format_exc())
        else:
            self._finish(DONE, value=value)

    def _finish(self, state, value=None, error=None, partial=None, tb="") -> None:
        with self._lock:
            self.state, self.value, self.error = state, value, error
            self.partial, self.traceback = partial, tb
            if state == DONE:
                self.fraction = 1.0
            self.finished_s = time.monotonic()
        self._ended.set()

    # ----------------------------------------------------------------- window side
    def cancel(self) -> None:
        """Ask the work to stop at its next progress call."""
        self._cancel.set()
        with self._lock:
            if self.state == RUNNING:
                self.message = "cancelling..."

    @property
    def cancel_requested(self) -> bool:
        return self._cancel.is_set()

    @property
    def running(self) -> bool:
        with self._lock:
            return self.state == RUNNING

    def snapshot(self) -> dict:
        """A consistent copy of the state: state, fraction, message, elapsed_s."""
        with self._lock:
            end = self.finished_s if self.finished_s is not None else time.monotonic()
            return {
                "state": self.state,
                "fraction": self.fraction,
                "message": self.message,
                "elapsed_s": end - self.started_s,
            }

    def wait(self, timeout: Optional[float] = None) -> bool:
        """Block until the work ends (for scripts, tests and closing); True if
        it did. An own event, not Thread.join: on Python 3.11 a join
        interrupted by Ctrl-C can mark a running thread as stopped."""
        return self._ended.wait(timeout)
