"""Exception types that say whose fault a failure is, and the command line's
exit codes.

* :class:`UsageError` (exit 2): the way qogi was called is wrong (a bad
  argument, an output path that cannot be written, a missing required fact
  such as the camera or distance). The message names what is wrong and how to
  fix it.
* :class:`DataError` (exit 3): the input data cannot give a trustworthy
  answer (an unreadable or forged file, non-physical radiance, too few
  frames). Both derive from :class:`ValueError`, so code that caught
  ValueError keeps working.

* :class:`NoSpaceError` (exit 3, a DataError and an OSError): the file
  system filled up while a file was written; the message names the folder.

* :class:`Cancelled` (exit 130): the work stopped because its progress
  callback returned False (qogi's one progress protocol, :mod:`qogi.progress`);
  ``.partial`` holds what was finished (e.g. the Result of the frames done),
  or None. The engine's cancellation arrives as this type too. Ctrl-C stays
  Python's ``KeyboardInterrupt``.

Anything else reaching the command line is a bug in qogi: it prints the
traceback and asks for a report (exit 1).
"""

from __future__ import annotations

import errno
from typing import Any

__all__ = [
    "QogiError",
    "UsageError",
    "DataError",
    "NoSpaceError",
    "Cancelled",
    "EXIT_OK",
    "EXIT_INTERNAL",
    "EXIT_USAGE",
    "EXIT_DATA",
    "EXIT_INTERRUPTED",
    "EXIT_CODES_HELP",
]

EXIT_OK = 0
EXIT_INTERNAL = 1
EXIT_USAGE = 2
EXIT_DATA = 3
EXIT_INTERRUPTED = 130

EXIT_CODES_HELP = (
    "exit status: 0 done; 1 internal error (a bug: please report it with the traceback); "
    "2 usage error (bad argument, unwritable output, missing scene fact); 3 bad data "
    "(unreadable file, non-physical input, a full disk, or a result that is "
    "NaN/incomplete); "
    "130 interrupted (Ctrl-C)"
)


class QogiError(ValueError):
    """Base of qogi's own errors: ``exit_code`` is the command line's status."""

    exit_code = EXIT_USAGE


class UsageError(QogiError):
    """Bad argument or environment: fix the call (exit 2)."""

    exit_code = EXIT_USAGE


class DataError(QogiError):
    """The input data cannot give a trustworthy answer (exit 3)."""

    exit_code = EXIT_DATA


class NoSpaceError(DataError, OSError):
    """The file system filled up while qogi wrote a file (exit 3): the
    message names the folder and the file; nothing already there was changed.
    Also an OSError with ``errno`` ENOSPC, so code that treats a failed write
    as an OSError (a cache that is skipped when it cannot be written) keeps
    doing so."""

    def __init__(self, message: str):
        super().__init__(message)
        self.errno = errno.ENOSPC


def is_no_space(exc: BaseException) -> bool:
    """Whether ``exc`` (an OSError, or h5py's/HDF5's error about a failed
    write) says the disk or the user's quota is full."""
    if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return True
    text = str(exc)
    return "No space left on device" in text or "Disk quota exceeded" in text


class Cancelled(Exception):
    """The work stopped because its progress callback returned False.

    ``.partial`` holds what was finished so far (:func:`qogi.quantify`: the
    Result of the frames finished, marked incomplete), or None. Derives from
    Exception, not KeyboardInterrupt: code that catches Exception (a viewer's
    job, a batch task) sees it as an ordinary outcome."""

    exit_code = EXIT_INTERRUPTED

    def __init__(self, message: str = "cancelled", partial: Any = None):
        super().__init__(message)
        self.partial = partial

    def __reduce__(self):
        return (type(self), (str(self), self.partial))
