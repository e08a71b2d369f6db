"""``make fuzz``: coverage-guided fuzzing (atheris, libFuzzer) of the FLIR and
recording readers, seeded with tests/data/fuzz/seeds.

    python tests/fuzz/run_fuzz.py flir [libFuzzer options, e.g. -max_total_time=600]
    python tests/fuzz/run_fuzz.py recording [...]
    python tests/fuzz/run_fuzz.py writers [...]   (root: on a small tmpfs it mounts)

``writers`` runs the file writers on a nearly full file system (the input
picks the free space, the writer and the size): each completes or raises
NoSpaceError, never anything else or a crash, and leaves nothing behind.

An input that makes a reader raise anything but DataError/OSError (or a
MemoryError) is kept in tests/data/fuzz/crashes, where
tests/python/test_fuzz.py replays it from then on; libFuzzer also stops on a
hang (-timeout, seconds per input) or a crash of the process.
"""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "python"))
os.environ["QOGI_FUZZ_KEEP"] = "1"  # findings go to tests/data/fuzz/crashes

import atheris  # noqa: E402
import h5py  # noqa: F401,E402  (libraries: not instrumented)
import numpy  # noqa: F401,E402

with atheris.instrument_imports(include=["qogi"]):
    import qogi
    import qogi.io.flir
    import qogi.io.recording  # noqa: F401

from fuzz_targets import (  # noqa: E402
    SEEDS,
    read_flir_bytes,
    read_recording_bytes,
    write_on_full_disk,
)

SUFFIXES = [".seq", ".csq", ".fff", ".jpg"]


def on_a_small_tmpfs() -> None:
    """``writers``: mounts a 512 KiB tmpfs, fuzzes in a child process (libFuzzer
    ends its process without unwinding) and unmounts it whatever happens."""
    scratch = tempfile.mkdtemp(prefix="qogi-fuzz-full-")
    try:
        r = subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=512k", "tmpfs", scratch], check=False
        )
        if r.returncode != 0:
            raise SystemExit("run_fuzz.py writers: needs root to mount a small tmpfs")
        try:
            env = dict(os.environ, QOGI_FUZZ_FULL=scratch)
            code = subprocess.run([sys.executable, *sys.argv], env=env, check=False).returncode
        finally:
            subprocess.run(["umount", scratch], check=False)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    raise SystemExit(code)


def main() -> None:
    target = sys.argv[1] if len(sys.argv) > 1 else "flir"
    if target == "writers" and "QOGI_FUZZ_FULL" not in os.environ:
        on_a_small_tmpfs()
    scratch = tempfile.mkdtemp(prefix="qogi-fuzz-")
    corpus = pathlib.Path(scratch) / "corpus"
    corpus.mkdir()
    for p in SEEDS.glob(("flir_" if target == "flir" else "recording_") + "*"):
        shutil.copy(p, corpus / p.name)

    if target == "flir":

        def one(data: bytes) -> None:
            # The first byte picks the file name's suffix (the reader's kind).
            if data:
                read_flir_bytes(data[1:], SUFFIXES[data[0] % len(SUFFIXES)], folder=scratch)

        # Seeds get a suffix byte in front.
        for p in corpus.iterdir():
            k = SUFFIXES.index(p.suffix) if p.suffix in SUFFIXES else 0
            p.write_bytes(bytes([k]) + p.read_bytes())
    elif target == "recording":

        def one(data: bytes) -> None:
            read_recording_bytes(data, folder=scratch)
    elif target == "writers":
        full = pathlib.Path(os.environ["QOGI_FUZZ_FULL"])
        for k, seed in enumerate((b"\0\0\0\7", b"\0\x10\1\3", b"\0\x40\2\x20", b"\xff\xff\3\1")):
            (corpus / f"writers_{k}").write_bytes(seed)

        def one(data: bytes) -> None:
            write_on_full_disk(data, full)
    else:
        raise SystemExit(f"unknown target {target!r}: flir, recording or writers")

    argv = [
        sys.argv[0],
        str(corpus),
        "-timeout=10",
        "-rss_limit_mb=4096",
        f"-artifact_prefix={scratch}/",
        "-print_final_stats=1",
    ] + sys.argv[2:]
    try:
        atheris.Setup(argv, one)
        atheris.Fuzz()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
