"""qogi's progress protocol: one callable signature from engine to viewer.

A progress callback is ``progress(fraction, message) -> bool | None``:
``fraction`` in [0, 1] of the whole call, ``message`` what is being done
(may be ""). Returning ``False`` (not merely a falsy value: None goes on)
asks the work to stop; it then raises :class:`qogi.Cancelled` carrying what
was finished in ``.partial``. :func:`qogi.quantify`, :func:`qogi.batch.run_batch`'s
tasks, the command line's progress bar (:class:`qogi._progress.ProgressBar`)
and the viewer's jobs all speak it.

The engine's loops (and a few long numpy loops) take the one-argument form
``progress(fraction) -> bool | None``; :func:`fraction_callback` adapts a
protocol callback to them for a part of the whole, and the engine's
cancellation arrives as :class:`qogi.Cancelled` too.
"""

from __future__ import annotations

from typing import Callable, Optional

from .errors import Cancelled

__all__ = ["Progress", "Cancelled", "report", "fraction_callback", "fraction_part", "wants_stop"]

#: The protocol's signature: (fraction in [0, 1], message) -> False to cancel.
Progress = Callable[[float, str], Optional[bool]]


def wants_stop(answer: object) -> bool:
    """True when a progress callback's answer asks to stop (``False``)."""
    return answer is False


def report(progress: Optional[Progress], fraction: float, message: str = "") -> None:
    """Reports ``fraction`` (clamped to [0, 1]) and ``message`` to
    ``progress`` (when given); raises :class:`qogi.Cancelled` when it
    answers False."""
    if progress is not None and wants_stop(progress(min(1.0, max(0.0, fraction)), message)):
        raise Cancelled("cancelled")


def fraction_callback(
    progress: Optional[Progress], message: str = "", start: float = 0.0, stop: float = 1.0
) -> Optional[Callable[[float], bool]]:
    """A one-argument callback for engine calls: its fraction f maps to
    ``start + (stop - start) f`` of ``progress``; it returns False when
    ``progress`` asks to stop (the engine then stops and raises
    :class:`qogi.Cancelled`). None for None."""
    if progress is None:
        return None

    def callback(fraction: float) -> bool:
        return not wants_stop(progress(start + (stop - start) * float(fraction), message))

    return callback


def fraction_part(
    callback: Optional[Callable[[float], object]], start: float, stop: float
) -> Optional[Callable[[float], object]]:
    """A one-argument callback (the engine's form) for a part of the work:
    its fraction f reaches ``callback`` as ``start + (stop - start) f``, and
    ``callback``'s answer comes back. None for None."""
    if callback is None:
        return None
    return lambda f: callback(start + (stop - start) * f)
