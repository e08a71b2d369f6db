"""A full file system: every writer ends with "no space left on <folder>"
(NoSpaceError, exit 3), never a traceback or a signal, and nothing is lost:
no temporary file stays behind and files already there are unchanged.

HDF5 flushes its caches when a file closes; on a full disk that flush failed,
the file stayed open inside the library and the interpreter's exit crashed
(SIGSEGV) after an internal-error traceback (issue 29). The writers are run
on a real full file system (a small tmpfs, mounted when the tests run as
root; skipped otherwise) in a child process, so a crash is seen as one.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import uuid

import numpy as np
import pytest
from fuzz_targets import write_on_full_disk
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_interrupt import SURFACE, small_recording

import qogi
from qogi.errors import EXIT_DATA, NoSpaceError

KEEP = b"a file that was there before\n"


def _mount_tmpfs(path, size_kib: int) -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    path.mkdir()
    r = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size_kib}k", "tmpfs", str(path)],
        capture_output=True,
        check=False,
    )
    return r.returncode == 0


@pytest.fixture
def tmpfs(tmp_path):
    """An empty folder on its own 256 KiB tmpfs."""
    folder = tmp_path / f"tmpfs-{uuid.uuid4().hex[:6]}"
    if not _mount_tmpfs(folder, 256):
        pytest.skip("needs root and mount to make a small tmpfs (a real full file system)")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=False)


@pytest.fixture
def full(tmpfs):
    """The tmpfs holding ``existing.h5`` and filled up to its last 8 KiB:
    writing anything larger fails with ENOSPC."""
    (tmpfs / "existing.h5").write_bytes(KEEP)
    st = os.statvfs(tmpfs)
    (tmpfs / "filler").write_bytes(b"\0" * (st.f_bavail * st.f_frsize - 8192))
    return tmpfs


def _untouched(folder):
    assert sorted(p.name for p in folder.iterdir()) == ["existing.h5", "filler"], (
        "a temporary or partial file was left behind"
    )
    assert (folder / "existing.h5").read_bytes() == KEEP


def _qogi(*argv, timeout=300):
    return subprocess.run(
        [sys.executable, "-m", "qogi", *map(str, argv)],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


def _no_space(r, command, folder, name):
    assert r.returncode == EXIT_DATA, f"exit {r.returncode} (negative: a signal)\n{r.stderr}"
    assert "Traceback" not in r.stderr, r.stderr
    assert f"qogi {command}: error: no space left on {folder} (writing {name})" in r.stderr, (
        r.stderr
    )


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return small_recording(tmp_path_factory.mktemp("full") / "small.h5", n_frames=12)


def test_convert_onto_a_full_disk_exits_3_and_keeps_the_existing_file(full, rec):
    r = _qogi("convert", rec, "-o", full / "existing.h5", "-q")
    _no_space(r, "convert", full, "existing.h5")
    assert "was left as it was" in r.stderr
    _untouched(full)


@pytest.mark.slow
def test_synth_onto_a_full_disk_exits_3_not_a_segfault(full):
    r = _qogi("synth", "lab-ch4-5slpm-gf320", "-o", full / "x.h5", "--duration", "0.5", "-q")
    _no_space(r, "synth", full, "x.h5")
    assert "nothing was written" in r.stderr
    _untouched(full)


def test_recording_writer_on_a_full_disk_raises_no_space_in_process(full, rec):
    """In process too (a library caller): NoSpaceError, an OSError with
    errno ENOSPC and a DataError, and the interpreter goes on (the HDF5 file
    was closed, not left open)."""
    code = (
        "import sys, qogi\n"
        "from qogi.errors import NoSpaceError\n"
        "r = qogi.open_recording(sys.argv[1]).load()\n"
        "for k in range(3):\n"
        "    try:\n"
        "        qogi.write_recording(sys.argv[2], r)\n"
        "    except NoSpaceError as e:\n"
        "        assert e.errno == 28 and isinstance(e, (OSError, ValueError)), e\n"
        "        print('refused', k)\n"
        "import gc; gc.collect(); print('alive')\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", code, str(rec), str(full / "w.h5")],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stderr}"
    assert r.stdout.split() == ["refused", "0", "refused", "1", "refused", "2", "alive"]
    assert "Exception ignored" not in r.stderr, r.stderr
    _untouched(full)


def test_quantify_outputs_on_a_full_disk_are_all_or_nothing(full, rec, tmp_path):
    """--json, --csv, --plot on the full disk: exit 3 naming the folder; no
    output replaced (not the JSON without the CSV)."""
    (full / "existing.h5").unlink()
    (full / "r.json").write_bytes(KEEP)
    r = _qogi(
        "quantify",
        rec,
        "--surface",
        SURFACE,
        "--source",
        "16,22",
        "-q",
        "--json",
        full / "r.json",
        "--csv",
        full / "r.csv",
        "--plot",
        full / "r.png",
    )
    assert r.returncode == EXIT_DATA, r.stderr
    assert "Traceback" not in r.stderr and f"no space left on {full}" in r.stderr, r.stderr
    assert sorted(p.name for p in full.iterdir()) == ["filler", "r.json"]
    assert (full / "r.json").read_bytes() == KEEP


def test_small_writers_on_a_full_disk_raise_no_space(full, rec):
    """The array and text writers (numpy's, a settings TOML) go through one
    atomic writer: NoSpaceError."""
    big = np.zeros(200_000)
    from qogi.files import atomic_path

    with pytest.raises(NoSpaceError, match=f"no space left on {full}"):
        with atomic_path(full / "a.npy") as tmp:
            np.save(tmp, big)
    surfaces = [qogi.Surface.parse(SURFACE, name=f"S{k}") for k in range(2000)]
    with pytest.raises(NoSpaceError):
        qogi.QuantifyConfig().to_toml(full / "existing.h5", surfaces=surfaces)
    _untouched(full)


def test_a_cache_on_a_full_disk_is_skipped_not_an_error(full):
    from qogi.cache import store

    def write(tmp):
        tmp.write_bytes(b"\1" * 100_000)

    assert store(full / "cache.bin", write) is False
    _untouched(full)


def test_check_outputs_refuses_a_folder_with_no_free_byte_before_any_work(full):
    from qogi.files import check_outputs

    st = os.statvfs(full)
    with open(full / "last", "wb") as fh:  # the last free blocks
        try:
            fh.write(b"\0" * st.f_bavail * st.f_frsize)
        except OSError:
            pass
    with pytest.raises(NoSpaceError, match="no space left"):
        check_outputs({"--json": full / "r.json"})


@settings(deadline=None, derandomize=True, database=None, max_examples=40,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(data=st.binary(min_size=4, max_size=4))
def test_writers_on_a_nearly_full_disk_complete_or_raise_no_space(tmpfs, data):
    """The fuzz target of ``make fuzz`` (writers), bounded: the free space,
    the writer and the size drawn; each write completes or is NoSpaceError,
    with nothing left behind."""
    assert write_on_full_disk(data, tmpfs) in ("written", "no space")


def test_the_writers_fuzz_target_sees_both_outcomes(tmpfs):
    outcomes = {
        write_on_full_disk(bytes([0, free, kind, 40]), tmpfs)
        for free in (0, 0xFF)
        for kind in range(4)
    }
    assert outcomes == {"written", "no space"}


def test_all_or_nothing_replaces_every_output_or_none(tmp_path, rec):
    """No full disk needed: the group's logic on an ordinary folder."""
    from qogi.files import all_or_nothing, atomic_open
    from qogi.io.recording import write_recording

    a, b, h5 = tmp_path / "a.json", tmp_path / "b.csv", tmp_path / "c.h5"
    for p in (a, b, h5):
        p.write_bytes(KEEP)

    def three_outputs():
        with all_or_nothing():
            with atomic_open(a) as fh:
                fh.write("new a")
            with atomic_open(b) as fh:
                fh.write("new b")
            raise RuntimeError("the third output failed")

    with pytest.raises(RuntimeError, match="the third output failed"):
        three_outputs()
    assert a.read_bytes() == b.read_bytes() == KEEP
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.csv", "c.h5"]
    with all_or_nothing():
        with atomic_open(a) as fh:
            fh.write("new a")
        assert a.read_bytes() == KEEP  # not before the group completes
        write_recording(h5, qogi.open_recording(rec))  # a writer with its own temporary
    assert a.read_text() == "new a" and qogi.open_recording(h5).n_frames == 12
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.csv", "c.h5"]
