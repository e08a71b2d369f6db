"""What the fuzzers feed garbage to, and what garbage may do.

A reader given any bytes must either read them or raise an error that says
the data is bad: :class:`qogi.errors.DataError` (FlirFormatError and
RecordingError are DataErrors) or an OSError, with a message. Anything else
(another exception type, a crash, a hang, a MemoryError) is a finding. Used by
tests/python/test_fuzz.py (hypothesis, bounded, in ``make test``) and
tests/fuzz/run_fuzz.py (``make fuzz``: atheris, long).
"""

from __future__ import annotations

import os
import pathlib
import tempfile

import numpy as np

from qogi.errors import DataError

DATA = pathlib.Path(__file__).resolve().parents[1] / "data" / "fuzz"
SEEDS = DATA / "seeds"
CRASHES = DATA / "crashes"

#: What a reader may raise on garbage.
ALLOWED = (DataError, OSError)


def seeds(prefix: str) -> list:
    """(name, bytes) of the seed files whose name starts with ``prefix``."""
    return [(p.name, p.read_bytes()) for p in sorted(SEEDS.glob(prefix + "*"))]


def _checked(exc: BaseException, data: bytes, name: str) -> None:
    """Accepts an allowed error; otherwise keeps the input in
    tests/data/fuzz/crashes (a regression test from then on) and fails."""
    bad = isinstance(exc, MemoryError) or not isinstance(exc, ALLOWED)
    if not bad and str(exc).strip():
        return
    what = (
        f"raised {type(exc).__name__}: {exc}" if bad else f"{type(exc).__name__} without a message"
    )
    if os.environ.get("QOGI_FUZZ_KEEP"):  # make fuzz: keep the input for the regression test
        import hashlib

        CRASHES.mkdir(parents=True, exist_ok=True)
        kept = CRASHES / f"{name}-{hashlib.sha1(data).hexdigest()[:12]}"
        kept.write_bytes(data)
        what += f" (input kept as {kept.relative_to(DATA.parents[1])})"
    raise AssertionError(f"garbage {what}") from exc


def read_flir_bytes(data: bytes, suffix: str = ".seq", folder=None) -> int:
    """Opens ``data`` as a FLIR file and reads every frame and its
    temperatures. Returns the number of frames read; raises AssertionError on
    a finding."""
    from qogi.io import flir

    with tempfile.TemporaryDirectory(dir=folder) as d:
        p = os.path.join(d, "input" + suffix)
        with open(p, "wb") as fh:
            fh.write(data)
        try:
            with flir.open_flir(p) as f:
                n = 0
                for i in range(len(f)):
                    fr = f.frame(i)
                    m = fr.metadata
                    assert fr.raw.dtype == np.uint16 and fr.raw.shape == (m.height, m.width)
                    with np.errstate(all="ignore"):
                        flir.flir_apparent_temperature(fr.raw[:2, :2], m)
                    n += 1
                return n
        except Exception as e:  # noqa: BLE001 - the point: which ones
            _checked(e, data, "flir" + suffix)
            return -1


def read_recording_file(path, data: bytes = b"") -> int:
    """Opens a recording file and reads every frame in both quantities;
    returns the frame count (-1: refused with an allowed error)."""
    import qogi

    try:
        with qogi.open_recording(path, nonfinite="invalid") as rec:
            for k in range(rec.n_frames):
                rec.frame(k, quantity="radiance")
                rec.frame(k, quantity="radiometric_temperature")
            _ = (rec.camera, rec.scene, rec.truth, rec.time_s, rec.duration_s)
            return rec.n_frames
    except Exception as e:  # noqa: BLE001
        _checked(e, data or pathlib.Path(path).read_bytes(), "recording.h5")
        return -1


def read_recording_bytes(data: bytes, folder=None) -> int:
    with tempfile.TemporaryDirectory(dir=folder) as d:
        p = os.path.join(d, "input.h5")
        with open(p, "wb") as fh:
            fh.write(data)
        return read_recording_file(p, data)


#: What a writer may raise on a full file system.
_KEEP = b"written before the fuzzed writer ran\n"


def write_on_full_disk(data: bytes, folder) -> str:
    """A writer on a nearly full file system (``folder``: an otherwise empty
    small tmpfs). ``data`` picks the free space left (0-64 KiB), the writer
    (a recording through write_recording or RecordingWriter, text through
    atomic_open, arrays through numpy's savez) and how much it writes. The
    write completes or raises NoSpaceError naming ``folder``; either way no
    temporary file is left and the file already there is unchanged.
    Returns "written" or "no space"; raises AssertionError on a finding."""
    import qogi
    from qogi.errors import NoSpaceError
    from qogi.files import atomic_open, atomic_path

    b = (data or b"\0") + bytes(4)
    free = int.from_bytes(b[0:2], "little")  # bytes left free: 0-64 KiB
    kind = b[2] % 4
    size = 1 + b[3] % 64  # frames or KiB
    folder = pathlib.Path(folder)
    target = folder / "target.out"
    target.write_bytes(_KEEP)
    st = os.statvfs(folder)
    filler = folder / "filler"
    try:
        with open(filler, "wb") as fh:
            fh.write(bytes(max(0, st.f_bavail * st.f_frsize - free)))
    except OSError:
        pass  # full already
    outcome = "written"
    try:
        if kind in (0, 1):
            rng = np.random.default_rng(size)
            frames = (50.0 + rng.random((size, 1, 24, 32))).astype(np.float32)
            cam = qogi.Camera(
                "fuzz", 1e-3, [qogi.SpectralResponse([2941.0, 3125.0], [1.0, 1.0])], 15.0
            )
            scene = qogi.Scene(distance_m=3.0, ambient_temperature_K=288.0, pressure_Pa=1e5)
            rec = qogi.Recording.from_arrays(frames, quantity="radiance", camera=cam, scene=scene)
            if kind == 0:
                qogi.write_recording(target, rec)
            else:
                with qogi.RecordingWriter(
                    target, quantity="radiance", camera=cam, scene=scene, frame_shape=(1, 24, 32)
                ) as w:
                    for k in range(size):
                        w.append(frames[k], k / 15.0)
        elif kind == 2:
            with atomic_open(target, "w") as fh:
                fh.write("x" * 1024 * size)
        else:
            with atomic_path(target, suffix=".npz") as tmp:
                np.savez(tmp, a=np.arange(128 * size, dtype=np.float64))
    except NoSpaceError as e:
        if f"no space left on {folder}" not in str(e):
            raise AssertionError(f"NoSpaceError without the folder: {e}") from e
        outcome = "no space"
    except Exception as e:
        raise AssertionError(f"a full disk raised {type(e).__name__}: {e}") from e
    finally:
        filler.unlink(missing_ok=True)
    left = sorted(p.name for p in folder.iterdir())
    if left != ["target.out"]:
        raise AssertionError(f"files left behind: {left}")
    if outcome == "no space" and target.read_bytes() != _KEEP:
        raise AssertionError("a failed write changed the file that was there")
    if outcome == "written" and target.read_bytes() == _KEEP:
        raise AssertionError("a write that returned did not replace the file")
    target.unlink()
    return outcome
