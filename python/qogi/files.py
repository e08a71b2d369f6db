"""Writing files so that nothing already on disk is lost.

Every file qogi writes goes to a temporary name in the target's folder, is
flushed and fsynced, and only then renamed over the target (``os.replace`` is
atomic on POSIX and Windows within one file system). An interrupted or failed
write leaves the previous file untouched and no temporary behind.

:func:`check_outputs` checks output paths before any computation: each folder
exists and is writable, no output is one of the inputs, no two outputs are the
same file.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import tempfile
from typing import IO, Iterable, Iterator, Optional, Union

from .errors import UsageError

__all__ = ["atomic_path", "atomic_open", "check_outputs"]

PathLike = Union[str, "os.PathLike[str]"]

_TMP_PREFIX = ".qogi-tmp-"


@contextlib.contextmanager
def atomic_path(target: PathLike, *, suffix: Optional[str] = None) -> Iterator[pathlib.Path]:
    """A temporary path beside ``target``; renamed onto it when the block ends
    without an exception, removed otherwise (also on KeyboardInterrupt).

    ``suffix`` (default: the target's) keeps writers that choose a format from
    the file name (matplotlib, numpy) working.
    """
    target = pathlib.Path(target)
    folder = target.parent if str(target.parent) else pathlib.Path(".")
    sfx = target.suffix if suffix is None else suffix
    fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX + target.name + ".", suffix=sfx, dir=folder)
    os.close(fd)
    tmp_path = pathlib.Path(tmp)
    try:
        yield tmp_path
        _fsync_file(tmp_path)
        try:
            mode = os.stat(target).st_mode & 0o7777 if target.exists() else _default_mode()
            os.chmod(tmp_path, mode)
        except OSError:
            pass
        os.replace(tmp_path, target)
        _fsync_dir(folder)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


@contextlib.contextmanager
def atomic_open(target: PathLike, mode: str = "w", **kwargs) -> Iterator[IO]:
    """``open(target, mode)`` that replaces ``target`` only when the block
    completes (see :func:`atomic_path`)."""
    if not mode.startswith("w"):
        raise ValueError(f"atomic_open writes new files only; mode {mode!r}")
    with atomic_path(target) as tmp:
        with open(tmp, mode, **kwargs) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())


def _default_mode() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def _fsync_file(path: pathlib.Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _fsync_dir(folder: pathlib.Path) -> None:
    if os.name != "posix":
        return
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _same_file(a: pathlib.Path, b: pathlib.Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.abspath(a) == os.path.abspath(b)


def _can_create_in(folder: pathlib.Path) -> bool:
    """Whether a file can really be created in ``folder`` (os.access says yes
    to root on read-only mounts and pseudo file systems such as /proc)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX + "probe.", dir=folder)
    except OSError:
        return False
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(tmp)
    return True


def check_outputs(outputs: dict, inputs: Iterable[PathLike] = ()) -> None:
    """Refuse output paths that would fail or destroy something, before any work.

    ``outputs`` maps an option name (``"--json"``) to a path (None entries and
    ``"-"`` for standard output are skipped). Raises :class:`UsageError`
    naming the option and the fix when a folder is missing or not writable, a
    path is a folder, an output is an input, or two outputs are the same file.
    """
    ins = [pathlib.Path(p) for p in inputs if p is not None]
    seen: dict = {}
    for name, p in outputs.items():
        if p is None or str(p) == "-":
            continue
        path = pathlib.Path(p)
        for i in ins:
            if _same_file(path, i):
                raise UsageError(
                    f"{name} {path}: that is the input file; writing it would "
                    "destroy the input. Choose another output path."
                )
        for other_name, other in seen.items():
            if _same_file(path, other):
                raise UsageError(
                    f"{name} and {other_name} both name {path}; give each output its own path."
                )
        if path.is_dir():
            raise UsageError(f"{name} {path}: is a folder; give a file path.")
        folder = path.parent if str(path.parent) else pathlib.Path(".")
        if not folder.is_dir():
            raise UsageError(
                f"{name} {path}: folder {folder} does not exist; create it first "
                f"(mkdir -p {folder})."
            )
        if not os.access(folder, os.W_OK | os.X_OK) or not _can_create_in(folder):
            raise UsageError(
                f"{name} {path}: folder {folder} is not writable; choose another "
                "folder or fix its permissions."
            )
        if path.exists() and not os.access(path, os.W_OK) and not os.access(folder, os.W_OK):
            raise UsageError(f"{name} {path}: exists and cannot be replaced.")
        seen[name] = path
