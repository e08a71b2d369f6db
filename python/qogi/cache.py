"""qogi's per-user cache on disk: where it lives, versioned file names, atomic
writes.

Every file qogi derives and keeps for reuse (cross-section tables, the
viewer's demo recording) lives in :func:`cache_dir` under a name from
:func:`cache_path`, which carries the writer's format version: a file written
by another format version has another name, so it is never read (nor
misread) and is rebuilt beside it. :func:`store` writes through
:func:`qogi.files.atomic_path` (a reader never sees a half-written file); a
cache that cannot be written (read-only, full) is logged and skipped, never an
error. Process-memory caches (band tables, scene tables, forward models) hold
no files and need no version.
"""

from __future__ import annotations

import logging
import os
import pathlib
import re
from typing import Callable, Union

from .files import atomic_path

__all__ = ["cache_dir", "cache_path", "store"]

log = logging.getLogger("qogi.cache")

_PART_RE = re.compile(r"^[A-Za-z0-9_.+-]+$")


def cache_dir() -> pathlib.Path:
    """Per-user cache folder: ``$QOGI_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/qogi``, else ``~/.cache/qogi``."""
    env = os.environ.get("QOGI_CACHE_DIR")
    if env:
        return pathlib.Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = pathlib.Path(xdg).expanduser() if xdg else pathlib.Path.home() / ".cache"
    return base / "qogi"


def cache_path(kind: str, stem: str, version: Union[int, str], suffix: str) -> pathlib.Path:
    """``cache_dir() / kind / "<stem>.v<version><suffix>"``.

    ``version`` is the format version of what the writer puts in the file
    (bump it whenever the bytes or their meaning change); ``suffix`` the
    extension with its dot (``".qxs"``, ``".h5"``).
    """
    for what, part in (("kind", kind), ("stem", stem), ("version", str(version))):
        if not _PART_RE.match(part):
            raise ValueError(f"cache {what} {part!r} must be letters, digits and _ . + -")
    return cache_dir() / kind / f"{stem}.v{version}{suffix}"


def store(path: Union[str, os.PathLike], write: Callable[[pathlib.Path], None]) -> bool:
    """Writes a cache file atomically: ``write(tmp)`` fills a temporary file
    beside ``path`` (same extension), renamed onto ``path`` when it returns.
    Returns False, with a warning in the log, when the cache cannot be
    written (the computation goes on without it); any other exception of
    ``write`` propagates and leaves nothing behind."""

    path = pathlib.Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path) as tmp:
            write(tmp)
    except OSError as e:  # a read-only cache must not stop the computation
        log.warning("could not write the cache file %s: %s", path, e)
        return False
    return True
