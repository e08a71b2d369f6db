"""The audit record of a run: what was measured, from which file, when, by
which qogi, and who and where (issue 28, item 5).

:func:`qogi.quantify` stamps every :class:`qogi.Result` with
:func:`run_record` (``Result.audit``); the JSON holds it as ``"audit"``, the
summary CSV and the batch table as columns, the PDF report in its header.
The record's own fields:

* ``recording_sha256``: SHA-256 (hex) of the file the frames were read from
  (the raw camera file itself for FLIR and Telops files); None for a
  recording held in memory;
* ``recording_time_utc``: the first frame's capture time (ISO 8601, UTC),
  where the file says it (FLIR and Telops headers); None otherwise;
* ``run_started_utc``, ``run_finished_utc``: the run's own start and end;
* ``qogi_version``;

and, from the run's settings (role ``record``, :mod:`qogi.pipeline.settings`), the
optional ``site``, ``component``, ``operator`` and ``location``.
"""

from __future__ import annotations

import datetime
import hashlib
import math
from typing import Optional

from ._version import __version__
from .files import PathLike

__all__ = ["AUDIT_FIELDS", "RECORD_SETTINGS", "file_sha256", "utc_text", "run_record"]

#: The record's own fields, in their saved order.
AUDIT_FIELDS = (
    "recording_sha256",
    "recording_time_utc",
    "run_started_utc",
    "run_finished_utc",
    "qogi_version",
)
#: The settings of role ``record`` (qogi.pipeline.settings) the audit record repeats.
RECORD_SETTINGS = ("site", "component", "operator", "location")


def file_sha256(path: Optional[PathLike], block: int = 1 << 20) -> Optional[str]:
    """SHA-256 of a file (hex), or None when there is no file or it cannot
    be read."""
    if path is None:
        return None
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for chunk in iter(lambda: fh.read(block), b""):
                h.update(chunk)
    except (OSError, TypeError):
        return None
    return h.hexdigest()


def utc_text(posix_s: Optional[float]) -> Optional[str]:
    """A POSIX time [s] as ISO 8601 in UTC to the millisecond
    (``2026-11-28T05:32:36.125Z``); None for None or a non-finite time."""
    if posix_s is None:
        return None
    try:
        t = float(posix_s)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(t):
        return None
    when = datetime.datetime.fromtimestamp(t, datetime.timezone.utc)
    return when.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def run_record(recording, started_s: float, finished_s: float) -> dict:
    """The audit record's own fields (:data:`AUDIT_FIELDS`) of a run over
    ``recording`` (a :class:`qogi.Recording`) that started and finished at
    POSIX times ``started_s`` and ``finished_s`` [s]."""

    attrs = getattr(recording, "attrs", None) or {}
    start = attrs.get("start_time_posix_s")
    return {
        "recording_sha256": file_sha256(getattr(recording, "path", None)),
        "recording_time_utc": utc_text(start),
        "run_started_utc": utc_text(started_s),
        "run_finished_utc": utc_text(finished_s),
        "qogi_version": __version__,
    }
