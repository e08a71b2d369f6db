"""qogi batch: a manifest of short synthetic releases with exact truth (and one
corrupt file) quantified on Dask. Rates against each recording's own truth,
the failed row carrying the reader's message, a batch killed for real and
resumed, and the same batch on a scheduler started separately."""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
from dask.system import CPU_COUNT
from distributed import Client

import qogi
from qogi import synth
from qogi.apps import batch
from qogi.errors import UsageError
from qogi.physics.presets import camera_preset
from qogi.synth import render

# Small frames keep the test quick: a 160x128 window of the GF320 lab scene
# (same pixel footprint), 1.5 s at 15 Hz, the exit 6 px above the bottom row.
W, H = 160, 128
EXIT = (W / 2 - 0.5, H - 6.0)
SURFACE = [EXIT[0] - 40, EXIT[1] - 20, EXIT[0] + 40, EXIT[1] - 20]  # 4 cm above the exit
ROWS = [
    ("a", "lab-ch4-5slpm-gf320", 1),
    ("b", "lab-ch4-10slpm-gf320", 2),
    ("c", "lab-ch4-5slpm-gf320", 3),
]


def small_release(preset, path, seed, duration_s=1.5):
    """A preset's release through a GF320 cropped to W x H (exact truth in /truth)."""
    p = synth.preset(preset)
    rel = synth.preset_release(preset)
    cam = dataclasses.replace(camera_preset("gf320"), width=W, height=H)
    view = synth.View.framing(
        rel,
        EXIT,
        width_px=W,
        height_px=H,
        ifov_rad=cam.ifov_rad,
        distance_m=p["scene"]["distance_m"],
        projection="orthographic",
    )
    sim = synth.simulate(rel, view, duration_s, 15.0, seed=seed, num_threads=1)
    bg = render.Background("plate", p["scene"]["background"]["temperature_K"])
    return render.render_recording(sim, cam, bg, path, seed=seed, num_threads=1)


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    d = tmp_path_factory.mktemp("clips")
    for name, preset, seed in ROWS:
        small_release(preset, d / f"{name}.h5", seed)
    # A file cut short (a copy that died half-way): HDF5 signature, no data.
    (d / "corrupt.h5").write_bytes((d / "a.h5").read_bytes()[:100_000])
    return d


def write_toml(folder, name="survey.toml"):
    s = ", ".join(f"{v:g}" for v in SURFACE)
    text = f"""# three releases and a broken file
[defaults]
species = ["CH4"]
surfaces = "auto"
auto_distances_px = [20, 30]

[[recording]]
path = "a.h5"
surfaces = [[{s}]]
source = [{EXIT[0]}, {EXIT[1]}]

[[recording]]
path = "b.h5"               # auto surfaces, source detected

[[recording]]
path = "c.h5"
surfaces = "{s}"
source = "{EXIT[0]},{EXIT[1]}"
gas_temperature = "ambient"
velocity = "fluid"

[[recording]]
path = "corrupt.h5"
"""
    p = folder / name
    p.write_text(text)
    return p


def write_csv(folder, name="survey.csv"):
    s = ",".join(f"{v:g}" for v in SURFACE)
    src = f"{EXIT[0]},{EXIT[1]}"
    lines = [
        "path,name,surfaces,auto_distances_px,source,species",
        f'a.h5,a,"{s}",,"{src}",CH4',
        "b.h5,b,auto,20;30,,CH4",
        "# a comment line",
        f'c.h5,c,"{s}",,"{src}",CH4',
        "corrupt.h5,corrupt,auto,20;30,,CH4",
    ]
    p = folder / name
    p.write_text("\n".join(lines) + "\n")
    return p


def truth_kg_h(path):
    with qogi.open_recording(path) as rec:
        return rec.truth.emission_rate_kg_s["CH4"] * 3600.0


def reader_error(path):
    try:
        qogi.open_recording(path)
    except Exception as e:  # noqa: BLE001 - whatever the reader raises is the expectation
        return type(e).__name__, str(e)
    raise AssertionError(f"{path} opened")


def rate_columns(df, name):
    row = df.set_index("name").loc[name]
    keys = sorted(
        {
            c.rsplit(" ", 1)[0]
            for c in df.columns
            if c.endswith(" mean_kg_h") and np.isfinite(row[c])
        }
    )
    return row, keys


def check_three_ok_one_failed(df, clips):
    assert list(df["name"]) == ["a", "b", "c", "corrupt"]
    assert list(df["status"]) == ["ok", "ok", "ok", "failed"]
    for name, _, _ in ROWS:
        row, keys = rate_columns(df, name)
        truth = truth_kg_h(clips / f"{name}.h5")
        assert keys, f"{name}: no rates in the summary"
        for key in keys:
            lo, mean, hi = (
                row[f"{key} ci90_low_kg_h"],
                row[f"{key} mean_kg_h"],
                row[f"{key} ci90_high_kg_h"],
            )
            assert row[f"{key} truth_kg_h"] == pytest.approx(truth)
            # The release's truth inside the row's 90 % interval, the mean
            # near it (1.5 s of a lab plume: the interval is ~+-30 %).
            assert lo <= truth <= hi, (name, key, lo, mean, hi, truth)
            assert mean == pytest.approx(truth, rel=0.25)
    # 10 SLPM reads about twice 5 SLPM.
    b, kb = rate_columns(df, "b")
    a, ka = rate_columns(df, "a")
    assert b[f"{kb[0]} mean_kg_h"] / a[f"{ka[0]} mean_kg_h"] == pytest.approx(2.0, rel=0.3)
    bad = df.set_index("name").loc["corrupt"]
    etype, emsg = reader_error(clips / "corrupt.h5")
    assert (bad["error_type"], bad["error"]) == (etype, emsg)


@pytest.fixture(scope="module")
def first_batch(clips, tmp_path_factory):
    out = tmp_path_factory.mktemp("batch") / "out"
    df = batch.run(write_toml(clips), out, workers=2, progress=False)
    return out, df


@pytest.mark.slow
def test_four_recordings_on_two_workers_three_ok_one_failed(clips, first_batch):
    out, df = first_batch
    check_three_ok_one_failed(df, clips)
    # One summary, the same in both formats, and a result per recording.
    pd.testing.assert_frame_equal(pd.read_parquet(out / "summary.parquet"), df)
    csv = pd.read_csv(out / "summary.csv", keep_default_na=False, na_values=[""])
    assert list(csv["status"]) == list(df["status"])
    assert len(set(df["config_hash"])) == 4 and set(df["qogi_version"]) == {qogi.__version__}
    assert (df["run_time_s"] > 0).all() and not df["reused"].any()
    assert (df.loc[df["status"] == "ok", "cpu_time_s"] > 0).all()
    # Two workers share the CPUs: the engine of each gets half of them.
    assert set(df["engine_threads"]) == {max(1, CPU_COUNT // 2)}
    for name in ("a", "b", "c"):
        d = json.loads((out / name / "result.json").read_text())
        assert d["format"] == "qogi-result" and d["batch"]["status"] == "ok"
    fail = json.loads((out / "corrupt" / "failure.json").read_text())
    assert fail["batch"]["error"] == reader_error(clips / "corrupt.h5")[1]
    assert not list(out.glob("*/.qogi-tmp-*"))


@pytest.mark.slow
def test_a_row_gives_what_quantify_gives_on_its_own(clips, first_batch):
    # The row's settings reach the pipeline unchanged: the same call by hand.
    _, df = first_batch
    res = qogi.quantify(
        clips / "a.h5",
        [qogi.Surface([tuple(SURFACE[:2]), tuple(SURFACE[2:])])],
        qogi.QuantifyConfig(species=["CH4"], source=EXIT, num_threads=1),
    )
    row = df.set_index("name").loc["a"]
    assert row["S1/CH4 mean_kg_h"] == pytest.approx(
        res.surfaces[0].species["CH4"].mean_kg_h, rel=1e-9
    )


def run_cli(*args, **kw):
    return subprocess.run(
        [sys.executable, "-m", "qogi", *map(str, args)],
        capture_output=True,
        check=False,
        text=True,
        timeout=300,
        **kw,
    )


@pytest.mark.slow
def test_a_killed_batch_resumes_with_only_the_missing_rows(clips, tmp_path):
    manifest = write_csv(clips)
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "qogi",
            "batch",
            str(manifest),
            "-o",
            str(out),
            "--workers",
            "2",
            "-q",
        ],
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 180
        while not list(out.glob("*/result.json")) and time.monotonic() < deadline:
            assert proc.poll() is None, proc.stderr.read().decode()
            time.sleep(0.02)
    finally:
        # The whole batch, cluster included, dies at once (no clean-up runs).
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stderr.close()
    done = {
        p.parent.name: (p.stat().st_mtime_ns, p.stat().st_ino) for p in out.glob("*/result.json")
    }
    assert proc.returncode == -signal.SIGKILL
    assert 1 <= len(done) < 3, f"kill came too late to test resuming: {sorted(done)} done"

    r = run_cli("batch", manifest, "-o", out, "--workers", "2", "--resume")
    assert r.returncode == 3, r.stderr  # the corrupt row fails again
    assert f"{len(done)} of 4 rows already done" in r.stderr
    # The progress line: done, failed, remaining, throughput; the dashboard line.
    assert "1 failed, 0 remaining" in r.stderr and "recordings/h" in r.stderr
    assert "Dask dashboard" in r.stderr
    df = pd.read_parquet(out / "summary.parquet")
    check_three_ok_one_failed(df, clips)
    # Rows finished before the kill were read back, not recomputed.
    assert set(df.loc[df["reused"], "name"]) == set(done)
    for name, stamp in done.items():
        p = out / name / "result.json"
        assert (p.stat().st_mtime_ns, p.stat().st_ino) == stamp
    assert not list(out.glob("*/.qogi-tmp-*"))
    # Without --resume an existing batch is not overwritten by accident.
    r = run_cli("batch", manifest, "-o", out)
    assert r.returncode == 2 and "--resume" in r.stderr


def _read_scheduler_file(path, proc, seconds=60):
    """The scheduler's address once its file holds a whole JSON document.

    Dask creates the file and then writes it, so it can exist and still be
    empty or partial for a moment: wait for the whole document, not the name.
    """
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"exited {proc.returncode}"
        try:
            return json.loads(path.read_text())["address"]
        except (FileNotFoundError, json.JSONDecodeError, KeyError):
            time.sleep(0.05)
    raise AssertionError(f"{path} not written whole within {seconds} s")


@pytest.mark.slow
def test_the_same_batch_on_a_scheduler_started_separately(clips, first_batch, tmp_path):
    dask = [sys.executable, "-m", "dask"]
    sched_file = tmp_path / "scheduler.json"
    procs = []
    log = open(tmp_path / "cluster.log", "w")  # closed after the processes  # noqa: SIM115
    try:
        # Port 0: the system picks free ports; the address is read from the file.
        procs.append(
            subprocess.Popen(
                dask
                + [
                    "scheduler",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    "0",
                    "--no-dashboard",
                    "--scheduler-file",
                    str(sched_file),
                ],
                stdout=log,
                stderr=log,
            )
        )
        address = _read_scheduler_file(sched_file, procs[0])
        assert address.startswith("tcp://127.0.0.1:")
        procs.append(
            subprocess.Popen(
                dask
                + [
                    "worker",
                    address,
                    "--host",
                    "127.0.0.1",
                    "--nworkers",
                    "2",
                    "--nthreads",
                    "1",
                    "--no-dashboard",
                ],
                stdout=log,
                stderr=log,
            )
        )
        with Client(address, timeout=60) as c:
            c.wait_for_workers(2, timeout=120)
        out = tmp_path / "out"
        r = run_cli("batch", write_csv(clips), "-o", out, "--scheduler", address)
        assert r.returncode == 3, r.stderr
        assert "dashboard not available" in r.stderr
        df = pd.read_parquet(out / "summary.parquet")
        check_three_ok_one_failed(df, clips)
        assert all(w.startswith("tcp://127.0.0.1:") for w in df["worker"])
        # Two worker processes of one thread on this host share its CPUs.
        assert set(df["engine_threads"]) == {max(1, CPU_COUNT // 2)}
        # The same numbers as on the local cluster.
        ref = first_batch[1].set_index("name")
        got = df.set_index("name")
        for name in ("a", "b", "c"):
            _, keys = rate_columns(df, name)
            for key in keys:
                assert got.loc[name, f"{key} mean_kg_h"] == pytest.approx(
                    ref.loc[name, f"{key} mean_kg_h"], rel=1e-9
                )
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=30)
        log.close()


# -- the manifest, validated before anything runs ---------------------------


@pytest.fixture
def folder(tmp_path):
    for n in ("x.h5", "y.h5"):
        (tmp_path / n).write_bytes(b"")
    return tmp_path


def manifest(folder, text, name="m.csv"):
    p = folder / name
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "text, words",
    [
        ("path,surfaces,colour\nx.h5,auto,red\n", ["line 2", "unknown column 'colour'"]),
        (
            'path,surfaces,gas_temperature\nx.h5,"1,2,3,4",900\n',
            ["line 2", "gas_temperature", "[150, 600]"],
        ),
        ('path,surfaces,gas_temperature\nx.h5,"1,2,3,4",hot\n', ["line 2", "'gas_temperature'"]),
        (
            'path,surfaces\nx.h5,"1,2,3,4"\n# comment\nmissing.h5,"1,2,3,4"\n',
            ["line 4", "'path'", "does not exist"],
        ),
        ("path,surfaces\nx.h5,auto\n", ["line 2", "auto_distances_px"]),
        ('path,surfaces\nx.h5,"1,2,3"\n', ["line 2", "'surfaces'", "even number"]),
        ('path,surfaces\nx.h5,"1,2,3,4"\nx.h5,"1,2,3,4"\n', ["line 3", "'x'", "already used"]),
        ('path,surfaces,num_threads\nx.h5,"1,2,3,4",4\n', ["num_threads", "--threads"]),
        ('path,surfaces,camera\nx.h5,"1,2,3,4",nikon\n', ["'camera'", "gf320"]),
        ('path,surfaces,velocity\nx.h5,"1,2,3,4",wind\n', ["line 2", "wind_speed_m_s"]),
        ("path\nx.h5\n", ["line 2", "'surfaces' is missing"]),
    ],
)
def test_manifest_errors_name_the_row_and_column(folder, text, words):
    with pytest.raises(UsageError) as e:
        batch.load_manifest(manifest(folder, text))
    for w in words:
        assert w in str(e.value)


def test_toml_defaults_apply_to_every_row_and_rows_override_them(folder):
    (folder / "more.csv").write_text("path,name,species\ny.h5,why,CO2\n")
    p = manifest(
        folder,
        """
rows = "more.csv"
[defaults]
surfaces = [[1, 2, 30, 2], [1, 9, 30, 9, 40, 12]]
gas_temperature = 300.0
distance_m = 4.5
timeout_s = 60
[[recording]]
path = "x.h5"
gas_temperature = "infer"
frames = "2:20"
composition = {CH4 = 0.5, CO2 = 0.5}
species = ["CH4", "CO2"]
""",
        "m.toml",
    )
    rows = batch.load_manifest(p)
    assert [r.name for r in rows] == ["x", "why"]
    x, y = rows
    assert x.surfaces == [[(1, 2), (30, 2)], [(1, 9), (30, 9), (40, 12)]] == y.surfaces
    assert x.config.gas_temperature == "infer" and y.config.gas_temperature == 300.0
    assert x.config.frames == (2, 20) and x.config.composition == {"CH4": 0.5, "CO2": 0.5}
    assert y.config.species == ["CO2"] and x.config.distance_m == y.config.distance_m == 4.5
    assert x.timeout_s == y.timeout_s == 60 and x.path == str(folder / "x.h5")
    with pytest.raises(UsageError, match=r"\[\[recording\]\] #1.*'frames'"):
        batch.load_manifest(
            manifest(
                folder,
                '[[recording]]\npath = "x.h5"\nsurfaces = "auto"\n'
                'auto_distances_px = [5]\nframes = "9:3"\n',
                "n.toml",
            )
        )


def test_config_hash_follows_the_analysis_not_the_output_options(folder):
    base = 'path,surfaces,plots,timeout_s{}\nx.h5,"1,2,3,4",{},{}{}\n'
    h = [
        batch.load_manifest(manifest(folder, base.format(*v))).pop().config_hash()
        for v in [
            ("", "false", "10", ""),
            ("", "true", "99", ""),
            (",distance_m", "false", "10", ",3.0"),
        ]
    ]
    assert h[0] == h[1] != h[2]


def test_a_timeout_and_a_wrong_camera_fail_their_row_with_the_reason(clips, tmp_path):
    rows = batch.load_manifest(
        manifest(
            clips,
            "path,surfaces,timeout_s,camera\n"
            f'a.h5,"{",".join(map(str, SURFACE))}",1e-9,\n'
            f'b.h5,"{",".join(map(str, SURFACE))}",,fast-m150\n',
            "t.csv",
        )
    )
    slow = batch.run_row(
        {"row": rows[0], "outdir": str(tmp_path), "config_hash": "h", "threads": 1}
    )
    assert slow["status"] == "failed" and slow["error_type"] == "TimeoutError"
    assert "timed out after 1e-09 s" in slow["error"]
    cam = batch.run_row({"row": rows[1], "outdir": str(tmp_path), "config_hash": "h", "threads": 1})
    assert cam["status"] == "failed" and "4 channel(s)" in cam["error"]
    assert not (tmp_path / "a" / "result.json").exists()
    assert json.loads((tmp_path / "a" / "failure.json").read_text())["batch"]["status"] == "failed"


def test_the_command_line_refuses_a_bad_manifest_before_starting(folder):
    m = manifest(folder, 'path,surfaces,velocity\nx.h5,"1,2,3,4",telepathy\n')
    r = run_cli("batch", m, "-o", folder / "out")
    assert r.returncode == 2
    assert "line 2" in r.stderr and "velocity" in r.stderr and "fluid" in r.stderr
    assert not (folder / "out").exists()
    assert "batch" in run_cli("--help").stdout


@pytest.mark.slow
def test_an_environment_error_is_retried_then_recorded(clips, tmp_path):
    # The row's output folder is taken by a file: not bad input, so the task
    # raises, Dask reruns it (retries=1) and the row records the last error.
    out = tmp_path / "out"
    out.mkdir()
    (out / "a").write_text("in the way")
    m = manifest(clips, f'path,surfaces\na.h5,"{",".join(map(str, SURFACE))}"\n', "one.csv")
    df = batch.run(m, out, workers=1, retries=1, progress=False)
    row = df.iloc[0]
    assert (row["name"], row["status"], row["error_type"]) == ("a", "failed", "FileExistsError")
    assert "retried up to 1 times" in row["error"]
