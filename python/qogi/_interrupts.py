"""Ctrl-C and SIGTERM that land where Python cannot raise them.

Python turns a signal into an exception at the next bytecode; when that is
inside a weakref callback, a finaliser or a garbage-collector hook, the
exception is "ignored": printed as a traceback and dropped, and the command
runs on as if the user had never pressed Ctrl-C. While a command runs, the
command line replaces ``sys.unraisablehook`` so that such an interrupt is kept
(not printed) and takes effect at the next safe point: the next progress
report (which then cancels the run) or before any output file is written.
"""

from __future__ import annotations

import contextlib
import sys
from typing import Iterator, List, Optional, Type

_pending: List[Type[BaseException]] = []


class Terminated(KeyboardInterrupt):
    """SIGTERM (kill), handled like Ctrl-C so that temporary files go."""


def pending() -> Optional[Type[BaseException]]:
    """The first interrupt that was dropped by Python and not yet acted on."""
    return _pending[0] if _pending else None


def raise_pending() -> None:
    """Raises the dropped interrupt (KeyboardInterrupt or its SIGTERM kind)."""
    if _pending:
        kind = _pending[0]
        _pending.clear()
        raise kind()


@contextlib.contextmanager
def kept() -> Iterator[None]:
    """Inside the block an interrupt Python would drop is kept in
    :func:`pending` instead of printed as an ignored exception."""
    previous = sys.unraisablehook

    def hook(unraisable) -> None:
        kind = unraisable.exc_type
        if isinstance(kind, type) and issubclass(kind, KeyboardInterrupt):
            _pending.append(kind)
            return
        previous(unraisable)

    sys.unraisablehook = hook
    _pending.clear()
    try:
        yield
    finally:
        sys.unraisablehook = previous
        _pending.clear()
