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
import threading
from typing import IO, Iterable, Iterator, Optional, Union

from .errors import NoSpaceError, UsageError, is_no_space

__all__ = ["atomic_path", "atomic_open", "all_or_nothing", "check_outputs", "no_space"]

PathLike = Union[str, "os.PathLike[str]"]

_TMP_PREFIX = ".qogi-tmp-"
_local = threading.local()  # this thread's all_or_nothing group


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
    try:
        fd, tmp = tempfile.mkstemp(prefix=_TMP_PREFIX + target.name + ".", suffix=sfx, dir=folder)
    except OSError as e:
        if is_no_space(e):
            raise no_space(target) from e
        raise
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
        group = getattr(_local, "group", None)
        # A target that is itself a temporary (a writer inside another
        # atomic_path, e.g. convert's) is renamed now: the outer one defers.
        if group is not None and not target.name.startswith(_TMP_PREFIX):
            group.append((tmp_path, target))  # renamed when the group completes
        else:
            os.replace(tmp_path, target)
            _fsync_dir(folder)
    except BaseException as e:
        # Some writers report a full disk as a short write without an errno
        # (numpy's tofile): the file system then has no free block left.
        full = is_no_space(e) or (isinstance(e, OSError) and _free_bytes(folder) == 0)
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        if full:  # named after this target (an inner writer's is a temporary)
            raise no_space(target) from e
        raise


@contextlib.contextmanager
def all_or_nothing() -> Iterator[None]:
    """Inside the block, files written through :func:`atomic_path` (and
    :func:`atomic_open`) replace their targets only when the whole block
    completes; an error (a full disk at the third of four outputs) or an
    interruption leaves every target as it was, so a set of outputs is never
    a mix of two runs. Nested groups belong to the outermost."""
    if getattr(_local, "group", None) is not None:
        yield
        return
    group: list = []
    _local.group = group
    try:
        yield
    except BaseException:
        for tmp, _target in group:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise
    finally:
        _local.group = None
    for tmp, target in group:
        os.replace(tmp, target)
    for folder in {t.parent if str(t.parent) else pathlib.Path(".") for _, t in group}:
        _fsync_dir(folder)


def no_space(target: PathLike) -> NoSpaceError:
    """The error for a write of ``target`` that found its file system full."""
    target = pathlib.Path(target)
    folder = target.parent if str(target.parent) else pathlib.Path(".")
    kept = f"{target} was left as it was" if target.exists() else "nothing was written"
    return NoSpaceError(
        f"no space left on {folder} (writing {target.name}): free some space there or "
        f"write to another folder; {kept}"
    )


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
    """Flushes a file (or folder) to disk; best effort (OSError ignored)."""
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _fsync_dir(folder: pathlib.Path) -> None:
    """Flushes a folder's entries (a rename into it) where the OS allows it."""
    if os.name == "posix":
        _fsync_file(folder)


def _free_bytes(folder: pathlib.Path) -> Optional[int]:
    """Bytes this process may still write in ``folder``'s file system (root
    may use the blocks reserved for it; None where the OS does not say)."""
    try:
        st = os.statvfs(folder)
        root = os.geteuid() == 0
    except (OSError, AttributeError):  # no statvfs or geteuid on Windows
        return None
    return (st.f_bfree if root else st.f_bavail) * st.f_frsize


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
        if _free_bytes(folder) == 0:
            raise no_space(path)
        seen[name] = path
