"""The background job slot: one job at a time (opening a file, making the
demo, the quantification), polled from the window's thread."""

from __future__ import annotations

import sys
from typing import Callable, Optional

from ..jobs import Job

__all__ = ["Work"]


class Work:
    """The job running in the background, if any, and what to do when it ends.

    :meth:`poll` hands a finished job to the ``finished(job, snapshot)``
    given to :meth:`start`, once."""

    def __init__(self, vm):
        self.vm = vm
        self.job: Optional[Job] = None
        self.kind = ""
        self._handled = True
        self._finished: Optional[Callable] = None

    def reset(self, recording) -> None:
        pass  # a job outlives the recording it was started on (e.g. opening the next one)

    @property
    def busy(self) -> bool:
        """A background job (quantification, demo or opening) is running."""
        return self.job is not None and self.job.running

    def start(self, job: Job, kind: str, finished: Callable) -> None:
        self.job, self.kind, self._handled, self._finished = job, kind, False, finished
        job.start()

    def cancel(self) -> bool:
        """Ask the running job to stop; the window keeps running meanwhile."""
        if not self.busy:
            return self.vm.log.error("nothing is running")
        self.job.cancel()
        self.vm.log.info(f"cancelling the {self.job.name}...")
        return True

    def progress(self) -> Optional[dict]:
        """State of the current or last job (state, fraction, message, elapsed_s)."""
        return self.job.snapshot() if self.job is not None else None

    def poll(self) -> bool:
        """Take in a finished job's outcome; True when something finished."""
        job = self.job
        if job is None or job.running or self._handled:
            return False
        self._handled = True
        self._finished(job, job.snapshot())
        return True

    def report_failure(self, what: str, job: Job) -> None:
        e = job.error
        if isinstance(e, (ValueError, OSError)):
            self.vm.log.error(f"{what} failed: {e}")
        else:
            self.vm.log.error(
                f"{what} failed with an internal error ({type(e).__name__}: {e}); "
                "details were printed to the terminal"
            )
            if job.traceback:
                print(job.traceback, file=sys.stderr)

    def close(self) -> None:
        """Stop the job and wait until it has stopped. The wait is not cut
        short: a job thread left inside the engine when the interpreter exits
        aborts the process; a cancelled job stops at its next progress report
        (a fraction of a second)."""
        if self.job is None:
            return
        self.job.cancel()
        interrupted = None
        while True:
            try:
                if self.job.wait(0.1):
                    break
            except KeyboardInterrupt as e:  # finish waiting first
                interrupted = e
        if interrupted is not None:
            raise interrupted
