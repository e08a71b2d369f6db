"""Interrupting qogi (Ctrl-C, kill) at any moment: no abort, no hang, nothing
on disk lost. The first second of ``qogi quantify`` builds the scene's
inversion table on a worker thread inside the C++ engine; Ctrl-C there used to
abort the process ("FATAL: exception not rethrown") about one try in five,
because the interpreter exited while that thread was still in the engine."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import qogi

SURFACE = "4,10,28,10"
PREVIOUS = '{"previous": "a good result from an earlier run"}\n'


def small_recording(path, n_frames=12):
    """A 32 x 24 two-channel recording: a warm blob drifting up (blackbody)."""
    chs = [
        qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um"),
        qogi.SpectralResponse([2000.0, 2200.0], [1.0, 1.0], name="4.5-5.0 um"),
    ]
    t = np.arange(n_frames)[:, None, None]
    y = np.arange(24)[None, :, None]
    x = np.arange(32)[None, None, :]
    temp = 285.0 + 0.5 * x / 32 + 25.0 * np.exp(-((x - 16) ** 2 + (y - (20 - t)) ** 2) / 20.0)
    frames = np.stack([ch.band_radiance(temp.ravel()).reshape(temp.shape) for ch in chs], axis=1)
    cam = qogi.Camera("test camera", 1e-3, chs, frame_rate_hz=10.0, netd_K=0.02)
    scene = qogi.Scene(
        distance_m=3.0, ambient_temperature_K=288.0, pressure_Pa=101325.0, species=("CH4",)
    )
    qogi.Recording.from_arrays(frames, quantity="radiance", camera=cam, scene=scene).save(path)
    return path


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return small_recording(tmp_path_factory.mktemp("interrupt") / "small.h5", n_frames=40)


def _ctrl_c_on():
    # Python turns SIGINT into KeyboardInterrupt only when it starts with the
    # default disposition; a shell's background job starts with it ignored.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def quantify_cmd(rec, out_dir):
    # -u: the progress lines reach the pipe as they are printed.
    return [
        sys.executable,
        "-u",
        "-m",
        "qogi",
        "quantify",
        str(rec),
        "--surface",
        SURFACE,
        "--source",
        "16,22",
        "--json",
        str(out_dir / "out.json"),
        "--csv",
        str(out_dir / "out.csv"),
    ]


def interrupt_quantify(rec, out_dir, delay_s, after_table_starts):
    """Runs qogi quantify, sends SIGINT ``delay_s`` after the start (or after
    it reports building the scene's table); returns (returncode, stderr)."""
    (out_dir / "out.json").write_text(PREVIOUS)
    (out_dir / "out.csv").write_text("previous\n")
    p = subprocess.Popen(
        quantify_cmd(rec, out_dir),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_ctrl_c_on,
    )
    err_lines = []
    if after_table_starts:
        for line in p.stderr:  # the progress bar's first report names the table
            err_lines.append(line)
            if "inversion table" in line:
                break
    time.sleep(delay_s)
    p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        pytest.fail(f"qogi quantify hung after Ctrl-C at {delay_s:.2f} s")
    return p.returncode, "".join(err_lines) + err


def check_outcome(code, err, out_dir, label):
    # -SIGINT: the signal came while Python had not yet, or no longer, a
    # handler for it (start-up, or the interpreter's exit after the run):
    # harmless if the files are either untouched or the whole new result.
    # -SIGABRT / -SIGSEGV (the bug) or anything else fails.
    startup = (
        code in (1, -signal.SIGINT)
        and err.rstrip().endswith("KeyboardInterrupt")
        and "qogi/cli.py" not in err
    )
    assert code in (0, 130, -signal.SIGINT) or startup, (
        f"{label}: exit {code} (negative: killed by a signal)\n{err}"
    )
    if startup:  # Ctrl-C while Python imported qogi, before any of its code ran
        assert (out_dir / "out.json").read_text() == PREVIOUS, label
        return
    assert "FATAL" not in err and "terminate called" not in err, f"{label}: {err}"
    assert "Traceback" not in err or startup, f"{label}: {err}"
    assert not [p.name for p in out_dir.iterdir() if p.name.startswith(".qogi-tmp")], label
    if code == -signal.SIGINT:
        import json

        text = (out_dir / "out.json").read_text()
        assert text == PREVIOUS or json.loads(text)["complete"] is True, label
    elif code == 130:
        # Interrupted: the outputs of the earlier run are as they were, or
        # (Ctrl-C while they were being written) all of them are this run's.
        assert "interrupted" in err
        old = [
            (out_dir / "out.json").read_text() == PREVIOUS,
            (out_dir / "out.csv").read_text() == "previous\n",
        ]
        assert old in ([True, True], [False, False]), f"{label}: a mix of old and new outputs"
        if old == [False, False]:
            import json

            assert json.loads((out_dir / "out.json").read_text())["complete"] is True, label
    else:  # finished before the signal: a whole result replaced them
        import json

        assert json.loads((out_dir / "out.json").read_text())["complete"] is True


def test_ctrl_c_while_the_scene_table_is_built_neither_aborts_nor_loses_outputs(rec, tmp_path):
    codes = []
    for k, delay_s in enumerate((0.0, 0.1, 0.3)):
        out = tmp_path / f"run{k}"
        out.mkdir()
        code, err = interrupt_quantify(rec, out, delay_s, after_table_starts=True)
        check_outcome(code, err, out, f"Ctrl-C {delay_s} s into the table")
        codes.append(code)
    assert 130 in codes, codes  # not vacuous: a signal landed inside the run


@pytest.mark.slow
def test_ctrl_c_at_many_moments_of_the_first_seconds(rec, tmp_path):
    """30 moments: 0-0.6 s after the table starts, and 0.3-3 s after launch
    (imports, reading, table, inversion, velocimetry, writing)."""
    rng = np.random.default_rng(16)
    moments = [(float(d), True) for d in rng.uniform(0.0, 0.6, 15)]
    moments += [(float(d), False) for d in np.linspace(0.3, 3.0, 15)]
    codes = []
    for k, (d, rel) in enumerate(moments):
        out = tmp_path / f"run{k}"
        out.mkdir()
        code, err = interrupt_quantify(rec, out, d, after_table_starts=rel)
        check_outcome(
            code,
            err,
            out,
            f"Ctrl-C at {d:.2f} s ({'after the table starts' if rel else 'after launch'})",
        )
        codes.append(code)
    assert 130 in codes, codes  # not vacuous: signals landed inside the run


def test_quantify_in_process_leaves_no_engine_thread_behind(rec):
    """Cancelled through its progress callback at each of its first reports,
    quantify returns only when its worker threads have stopped."""
    # Stop at each stage of the first block: the table, the columns, the
    # inversion (the stages' reports of an uncancelled run).
    # (The number of reports varies from run to run: the engine reports as
    # its threads finish. So each stop is a report's stage and how far the
    # run had got, never its count.)
    reports: list = []
    qogi.quantify(
        qogi.open_recording(rec),
        [qogi.Surface.parse(SURFACE)],
        qogi.QuantifyConfig(source=(16.0, 22.0)),
        progress=lambda f, m: reports.append((f, m)),
    )
    kinds = ("cross-section", "background and column", "inverting")
    staged = [(f, m) for f, m in reports if m.startswith(kinds)]
    assert len(staged) >= 4, reports
    inverting = [f for f, m in staged if m.startswith("inverting")]
    assert inverting, reports
    stops = [(kind, 0.0) for kind in kinds if any(m.startswith(kind) for _, m in staged)]
    stops.append(("inverting", inverting[len(inverting) // 2]))
    for kind, at_least in stops:

        def progress(fraction, message, kind=kind, at_least=at_least):
            return not (message.startswith(kind) and fraction >= at_least)

        # Also inside the first block, before any block is finished: the
        # partial result is empty and says so (it used to fail to assemble).
        with pytest.raises(qogi.Cancelled) as e:
            qogi.quantify(
                qogi.open_recording(rec),
                [qogi.Surface.parse(SURFACE)],
                qogi.QuantifyConfig(source=(16.0, 22.0)),
                progress=progress,
            )
        if e.value.partial is not None:
            assert e.value.partial.complete is False
        left = [t.name for t in threading.enumerate() if t.name.startswith("qogi-")]
        assert left == [], f"stopped at {kind} ({at_least:.2f}): threads still running: {left}"


@pytest.mark.parametrize(
    "sig, code", [pytest.param(signal.SIGINT, 130, marks=pytest.mark.slow), (signal.SIGTERM, 143)]
)
def test_interrupted_synth_leaves_the_existing_recording_untouched(tmp_path, sig, code):
    target = small_recording(tmp_path / "existing.h5")
    before = target.read_bytes()
    p = subprocess.Popen(
        [
            sys.executable,
            "-u",
            "-m",
            "qogi",
            "synth",
            "lab-ch4-5slpm-gf320",
            "-o",
            str(target),
            "--duration",
            "4",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_ctrl_c_on,
    )
    end = time.monotonic() + 60
    while not any(q.name.startswith(".qogi-tmp-existing.h5") for q in tmp_path.iterdir()):
        assert p.poll() is None and time.monotonic() < end, "synth never started writing"
        time.sleep(0.05)
    time.sleep(0.3)  # the recording is being written beside the old one
    p.send_signal(sig)
    try:
        _, err = p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        p.kill()
        pytest.fail("qogi synth hung after the signal")
    assert p.returncode == code, err
    assert "Traceback" not in err
    assert target.read_bytes() == before
    assert sorted(q.name for q in tmp_path.iterdir()) == ["existing.h5"]  # no temporary


class _DropsACtrlC:
    """Raises KeyboardInterrupt from its finaliser: where Python cannot raise
    it, so it prints "Exception ignored" and drops it. A real Ctrl-C lands
    there when it arrives while a weakref callback or finaliser runs (seen in
    CI: the run went on and wrote its outputs, exit 0)."""

    def __del__(self):
        raise KeyboardInterrupt


def _drop_a_ctrl_c():
    _DropsACtrlC()  # collected at once: its finaliser's exception is dropped


@pytest.mark.parametrize("when", ["during the run", "after the run"])
def test_a_ctrl_c_python_drops_still_stops_quantify(rec, tmp_path, monkeypatch, capsys, when):
    from patching import replace_everywhere

    import qogi.pipeline as pipeline
    from qogi.apps.cli import main

    real = pipeline.quantify

    def quantify(rec_, surfaces, cfg, progress=None, **kw):
        calls = [0]

        def relay(fraction, message=""):
            calls[0] += 1
            if when == "during the run" and calls[0] == 3:
                _drop_a_ctrl_c()
            return progress(fraction, message)

        result = real(rec_, surfaces, cfg, progress=relay, **kw)
        if when == "after the run":
            _drop_a_ctrl_c()
        return result

    replace_everywhere(monkeypatch, real, quantify)
    (tmp_path / "out.json").write_text(PREVIOUS)
    argv = quantify_cmd(rec, tmp_path)[4:]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 130, err
    assert "interrupted" in err
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert (tmp_path / "out.json").read_text() == PREVIOUS
    assert not (tmp_path / "out.csv").exists()
    # Outside a command Python's own handling is back.
    from qogi import _interrupts

    assert _interrupts.pending() is None


def test_importing_the_command_line_loads_no_engine():
    """``import qogi`` (the console script's ``from qogi.apps.cli import main``)
    loaded the whole package, about 0.15-0.5 s, before main() could catch a
    Ctrl-C: it printed a KeyboardInterrupt traceback instead of exit 130.
    qogi's names now load on first use (PEP 562)."""
    code = (
        "import sys, qogi.apps.cli\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in "
        "('qogi', 'numpy', 'h5py', 'scipy')))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    ).stdout
    expected = ["qogi", "qogi._interrupts", "qogi._version", "qogi.apps", "qogi.apps.cli"]
    assert out.strip() == str(expected + ["qogi.errors"]), out


def test_every_public_name_still_loads_from_the_package():
    for name in qogi.__all__:
        assert getattr(qogi, name) is not None, name
    assert set(qogi.__all__) <= set(dir(qogi))
    from qogi import Result, quantify  # the from-import form too

    assert quantify.__module__ == "qogi.pipeline.run" and Result.__name__ == "Result"
    with pytest.raises(AttributeError, match="has no attribute 'nope'"):
        qogi.nope  # noqa: B018


# Ctrl-C delivered while one module loads (a real SIGINT, sent from an import
# hook when the import of that module starts), then `qogi info` run as the
# console script runs it: deterministic, whatever the machine's speed.
CTRL_C_IN_IMPORT = """
import os, runpy, signal, sys
target = sys.argv.pop(1)

class CtrlC:
    def find_spec(self, name, path=None, target_module=None):
        if name == target:
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, CtrlC())
sys.argv[0] = "qogi"
from qogi.apps.console import main  # what the console script and python -m qogi run
sys.exit(main())
"""


@pytest.mark.parametrize(
    "module",
    [
        "qogi.apps.cli",  # the command line itself, loaded inside the console entry's guard
        "argparse",
        "qogi._interrupts",
        "qogi.apps._cli_camera",
        "qogi.physics.presets",
        "numpy",
        "qogi._engine",
        "qogi.apps.info",
        "h5py",
    ],
)
def test_ctrl_c_while_qogi_info_loads_its_modules_exits_130(rec, module):
    """Ctrl-C in the first moments of ``qogi info`` landed in ``import qogi``
    (the whole package, about 0.15 s) and printed a KeyboardInterrupt
    traceback; inside the engine's or numpy's initialisation it arrives as
    an ImportError caused by it. Now: exit 130 and one line."""
    r = _info_interrupted(rec, CTRL_C_IN_IMPORT, module)
    assert r.stderr.strip() in ("qogi: interrupted", "qogi info: interrupted"), r.stderr


# A Ctrl-C inside numpy's C initialisation can be lost altogether: it surfaced
# as "ImportError: PyCapsule_Import could not import module 'datetime'" with no
# KeyboardInterrupt in its chain, and qogi printed an internal error (exit 1).
CTRL_C_LOST_IN_IMPORT = """
import os, signal, sys

class LosesACtrlC:
    def find_spec(self, name, path=None, target_module=None):
        if name == "numpy":
            sys.meta_path.remove(self)
            try:
                os.kill(os.getpid(), signal.SIGINT)
            except KeyboardInterrupt:
                pass  # C code clears it and fails its import
            raise ImportError("PyCapsule_Import could not import module 'datetime'")
        return None

sys.meta_path.insert(0, LosesACtrlC())
sys.argv[0] = "qogi"
from qogi.apps.console import main
sys.exit(main())
"""


def test_a_ctrl_c_lost_inside_an_import_still_exits_130(rec):
    _info_interrupted(rec, CTRL_C_LOST_IN_IMPORT)


def _info_interrupted(rec, script: str, *args: str):
    """``qogi info REC`` run by ``script`` (which delivers a Ctrl-C): exit 130, no traceback."""
    r = subprocess.run(
        [sys.executable, "-c", script, *args, "info", str(rec)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        preexec_fn=_ctrl_c_on,
    )
    assert r.returncode == 130, f"exit {r.returncode}\n{r.stderr}"
    assert "Traceback" not in r.stderr, r.stderr
    return r
