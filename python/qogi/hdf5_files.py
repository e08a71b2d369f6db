"""HDF5 files written safely and read within bounds: a full disk is an error
when a block ends (never a file HDF5 cannot close), text attributes are
written as fixed-length UTF-8, and a file's variable-length attributes and
metadata are read only after their size is checked (a forged heap length
would otherwise send libhdf5 into an unbounded read).
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
from typing import Optional, Union

import numpy as np

from .contract import RecordingError


def _h5py():
    import h5py

    return h5py


class GuardedFile(io.RawIOBase):
    """The file HDF5 writes a recording through (h5py's ``fileobj`` driver).

    A failed write (a full disk, a quota) is kept in :attr:`error` and every
    later write is dropped, so HDF5 itself never sees one fail. HDF5 that
    sees a write fail while it flushes its caches (at close, on a full disk)
    leaves the file open inside the library in a state in which closing it
    fails and the interpreter's exit crashes (SIGSEGV); through this file
    the close completes and :meth:`check` raises the write's error, after
    which the file is deleted (it is a temporary one,
    :func:`qogi.files.atomic_path`).
    """

    def __init__(self, path: Union[str, os.PathLike], mode: str = "w"):
        super().__init__()
        self._fh = open(path, "w+b" if mode == "w" else "r+b", buffering=0)  # noqa: SIM115
        self.error: Optional[OSError] = None

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, pos: int, whence: int = 0) -> int:
        return self._fh.seek(pos, whence)

    def tell(self) -> int:
        return self._fh.tell()

    def readinto(self, b) -> int:
        return self._fh.readinto(b)

    def write(self, b) -> int:
        n = memoryview(b).nbytes
        if self.error is None:
            try:
                done = self._fh.write(b)
                if done == n:
                    return n
                raise OSError(errno.ENOSPC, f"short write ({done} of {n} bytes)")
            except OSError as e:
                self.error = e
        self._fh.seek(n, 1)
        return n

    def truncate(self, size: Optional[int] = None) -> int:
        if self.error is None:
            try:
                return self._fh.truncate(size)
            except OSError as e:
                self.error = e
        return self._fh.tell() if size is None else size

    def flush(self) -> None:
        pass  # unbuffered: every write has reached the OS

    def close(self) -> None:
        if not self.closed:
            self._fh.close()
        super().close()

    def check(self) -> None:
        """Raises the first failed write's error (an OSError), if any."""
        if self.error is not None:
            raise self.error


@contextlib.contextmanager
def h5_writing(path: Union[str, os.PathLike], mode: str = "w"):
    """``h5py.File`` written through a :class:`GuardedFile`: a full disk is
    an OSError (ENOSPC) when the block ends, never a file HDF5 cannot close.
    ``mode`` "w" (create) or "a" (change an existing file)."""
    sink = GuardedFile(path, mode)
    try:
        f = _h5py().File(sink, "w" if mode == "w" else "r+")
    except BaseException:
        sink.close()
        raise
    try:
        yield f
    finally:
        try:
            f.close()
        finally:
            sink.close()
    sink.check()


#: Largest attribute or metadata dataset (channel responses, truth) read whole [bytes].
_MAX_METADATA_BYTES = 64 << 20


def set_attr(obj, name: str, value) -> None:
    """Writes an HDF5 attribute the way recordings store them: text as
    fixed-length UTF-8 (a string or a sequence of strings), anything else as
    given. Variable-length strings, h5py's default for ``str``, keep their
    bytes on a global heap whose forged lengths can send libhdf5 into an
    unbounded read; fixed-length ones are read whole after their declared
    size is checked (see :func:`_check_variable_length`)."""
    h5py = _h5py()
    if isinstance(value, str):
        b = value.encode("utf-8")
        obj.attrs.create(name, np.array(b, dtype=h5py.string_dtype("utf-8", max(1, len(b)))))
        return
    if (
        isinstance(value, (list, tuple, np.ndarray))
        and len(value)
        and all(isinstance(v, (str, np.str_)) for v in np.ravel(np.asarray(value, dtype=object)))
    ):
        enc = [str(v).encode("utf-8") for v in np.ravel(np.asarray(value, dtype=object))]
        n = max([1, *(len(b) for b in enc)])
        arr = np.array(enc, dtype=h5py.string_dtype("utf-8", n)).reshape(np.shape(value))
        obj.attrs.create(name, arr)
        return
    obj.attrs[name] = value


#: Bounds for reading a file's variable-length attributes in a child process:
#: address space [bytes], CPU time [s] and wall time [s]. A real attribute
#: of a few names reads in microseconds; a forged heap length makes libhdf5
#: allocate gigabytes or loop without end (tests/data/fuzz/crashes).
_PROBE_MEMORY_BYTES = 2 << 30
_PROBE_CPU_S = 5
_PROBE_WALL_S = 120.0
_probed_ok: set = set()

# Run by a fresh interpreter (numpy + h5py only): reads each variable-length
# attribute named on the command line, printing which one before reading it.
_PROBE_CODE = """
import json, resource, sys
mem, cpu = int(sys.argv[2]), int(sys.argv[3])
resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 1))
import h5py
with h5py.File(sys.argv[1], "r") as f:
    for obj, name in json.loads(sys.argv[4]):
        print(obj, name, flush=True)
        f[obj].attrs[name]
print("ok", flush=True)
"""


def _is_variable_length(type_id) -> bool:
    h5t = _h5py().h5t
    if isinstance(type_id, h5t.TypeStringID):
        return bool(type_id.is_variable_str())
    try:
        return bool(type_id.detect_class(h5t.VLEN))
    except Exception:  # noqa: BLE001 - a type libhdf5 cannot classify: treat as unsafe
        return True


def _check_variable_length(f, p: str) -> None:
    """Reads the variable-length attributes of a recording's metadata objects
    (older qogi files and other writers store text that way) in a child
    process bounded in memory and CPU time, before this process touches
    them; a forged one raises RecordingError naming it instead of hanging or
    exhausting memory. Passed files are remembered (path, size, mtime)."""
    import json
    import subprocess
    import sys

    h5py = _h5py()
    items = []
    objects = ["/", "/frames", "/time_s", "/camera", "/scene", "/truth"]
    ch = f.get("/camera/channels")
    if isinstance(ch, h5py.Group):
        objects += [f"/camera/channels/{k}" for k in list(ch.keys())[:64]]
    for o in objects:
        obj = f.get(o)
        if obj is None:
            continue
        for k in obj.attrs:
            try:
                tid = obj.attrs.get_id(k).get_type()
            except Exception:  # noqa: BLE001 - unreadable type: the normal read reports it
                continue
            if _is_variable_length(tid):
                items.append((o, k))
    if not items:
        return
    st = os.stat(p)
    key = (os.path.realpath(p), st.st_size, st.st_mtime_ns, tuple(items))
    if key in _probed_ok:
        return
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["OPENBLAS_NUM_THREADS"] = env["OMP_NUM_THREADS"] = "1"
    try:
        r = subprocess.run(
            [
                sys.executable,
                "-I",
                "-c",
                _PROBE_CODE,
                p,
                str(_PROBE_MEMORY_BYTES),
                str(_PROBE_CPU_S),
                json.dumps(items),
            ],
            capture_output=True,
            check=False,  # the exit status is read below
            text=True,
            timeout=_PROBE_WALL_S,
            env=env,
            stdin=subprocess.DEVNULL,
        )
        out, ok = r.stdout.split(), r.returncode == 0 and r.stdout.rstrip().endswith("ok")
        why = (r.stderr.strip().splitlines() or [f"exit status {r.returncode}"])[-1]
        if r.returncode < 0:
            why = {9: "killed at the CPU-time limit", 24: "stopped at the CPU-time limit"}.get(
                -r.returncode, f"killed by signal {-r.returncode}"
            )
    except subprocess.TimeoutExpired as e:
        out, ok, why = (e.stdout or b"").decode(errors="replace").split(), False, "timed out"
    if ok:
        _probed_ok.add(key)
        return
    where = f"{out[-2]} attr {out[-1]}" if len(out) >= 2 else "variable-length attributes"
    raise RecordingError(
        p,
        where,
        f"cannot be read within {_PROBE_MEMORY_BYTES >> 30} GiB and "
        f"{_PROBE_CPU_S} s of CPU ({why})",
        "the file is damaged or forged; write it again (qogi writes text "
        "attributes as fixed-length strings)",
    )


def _small(ds, path: str, location: str) -> np.ndarray:
    """A metadata dataset read whole, after checking its declared size."""
    size = int(ds.size) * int(ds.dtype.itemsize)
    if size > _MAX_METADATA_BYTES:
        raise RecordingError(
            path,
            location,
            f"shape {ds.shape} declares {size / 2**20:.3g} MiB of metadata",
            "the file is damaged or forged",
        )
    return ds[()]


def _attr(obj, name: str, path: str, location: str, required: bool = True, fix: str = ""):
    if name not in obj.attrs:
        if required:
            raise RecordingError(
                path,
                f"{location} attr {name}",
                "missing",
                fix or f"add the attribute {name} to {location}",
            )
        return None
    try:
        size = int(obj.attrs.get_id(name).get_storage_size())
    except Exception:  # noqa: BLE001 - unreadable: reported by the read below
        size = 0
    if size > _MAX_METADATA_BYTES:
        raise RecordingError(
            path,
            f"{location} attr {name}",
            f"declares {size / 2**20:.3g} MiB (an attribute holds a few numbers or a name)",
            "the file is damaged or forged",
        )
    v = obj.attrs[name]
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.dtype.kind == "S":  # fixed-length text
        v = np.char.decode(v, "utf-8", "replace")
    if isinstance(v, np.ndarray) and v.shape == ():
        v = v[()]
    if isinstance(v, np.generic):
        v = v.item()
    return v
