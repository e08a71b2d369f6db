"""Owned background threads: the one helper for background work in qogi.

A :class:`Workers` owns every thread it starts: :meth:`Workers.close`
cancels them (their :meth:`~Workers.still_wanted` turns False, which the
engine's progress hooks honour between chunks) and waits until each has left
its target, also on Ctrl-C. A thread left inside the C++ engine when the
interpreter exits is torn down while it holds C++ frames, which aborts the
process ("FATAL: exception not rethrown"), so no qogi code starts a thread of
its own: :func:`qogi.quantify` runs inside :func:`owned_workers`, and code
below it takes :func:`current` (e.g. :class:`qogi.pipeline.budget_terms.AlternativeModels`,
the pipeline's scene table, transport and proxy jobs). :meth:`Workers.submit`
returns a :class:`Task` whose :meth:`~Task.result` waits and re-raises the
work's exception on the caller's thread (the relay each job used to write).
"""

from __future__ import annotations

import contextlib
import contextvars
import threading
from typing import Any, Callable, Iterator, List, Optional

__all__ = ["Workers", "Task", "current", "owned_workers"]


class Task:
    """The outcome of one :meth:`Workers.submit`: :meth:`result` waits for
    it and returns the work's value or raises its exception."""

    def __init__(self) -> None:
        self._done = threading.Event()
        self._value: Any = None
        self._error: Optional[BaseException] = None

    def done(self) -> bool:
        return self._done.is_set()

    def wait(self) -> None:
        """Until the work has ended (own event, not Thread.join: see
        :meth:`Workers.close`)."""
        self._done.wait()

    def result(self) -> Any:
        self.wait()
        if self._error is not None:
            raise self._error
        return self._value


class Workers:
    """The worker threads of one run (see the module's docstring)."""

    def __init__(self) -> None:
        self.cancel = threading.Event()
        self._done: List[threading.Event] = []

    def still_wanted(self, fraction: float = 0.0) -> bool:
        """The progress callback of engine calls on a worker: False once the
        run is closing (the engine then stops at its next chunk)."""
        return not self.cancel.is_set()

    def start(self, target: Callable[[], None], name: str) -> threading.Thread:
        """Runs ``target()`` on an owned daemon thread named ``name``."""
        done = threading.Event()

        def run() -> None:
            try:
                target()
            finally:
                done.set()

        job = threading.Thread(target=run, name=name, daemon=True)
        self._done.append(done)
        job.start()
        return job

    def submit(self, fn: Callable[[], Any], name: str) -> Task:
        """Runs ``fn()`` on an owned thread; its value or exception (any
        BaseException, a cancellation included) comes back through
        :meth:`Task.result` on the caller's thread."""
        task = Task()

        def run() -> None:
            try:
                task._value = fn()
            except BaseException as e:  # noqa: BLE001 - re-raised by Task.result on the caller's thread
                task._error = e
            finally:
                task._done.set()

        self.start(run, name)
        return task

    def close(self) -> None:
        """Cancel every thread and wait until each has left its target (a
        Ctrl-C while waiting is deferred until they have). Own events, not
        Thread.join: on Python 3.11 a join interrupted by Ctrl-C can mark a
        running thread as stopped."""
        self.cancel.set()
        interrupted = None
        for done in self._done:
            while not done.is_set():
                try:
                    done.wait(0.05)
                except KeyboardInterrupt as e:
                    interrupted = e
        self._done.clear()
        if interrupted is not None:
            raise interrupted


_current: contextvars.ContextVar[Workers] = contextvars.ContextVar("qogi_run_workers")


def current() -> Workers:
    """The current run's :class:`Workers` (a fresh set outside a run)."""
    w = _current.get(None)
    if w is None:
        w = Workers()
        _current.set(w)
    return w


@contextlib.contextmanager
def owned_workers() -> Iterator[Workers]:
    """A fresh :class:`Workers` as :func:`current` inside the block, closed
    (cancelled and awaited) when the block ends, however it ends."""
    workers = Workers()
    token = _current.set(workers)
    try:
        yield workers
    finally:
        _current.reset(token)
        workers.close()
