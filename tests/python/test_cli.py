import json
import subprocess
import sys


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "qogi", *args], capture_output=True, check=False, text=True
    )


def test_help_lists_commands():
    out = run("--help").stdout
    for cmd in ("demo", "synth", "quantify", "info", "xsec"):
        assert cmd in out


def test_synth_then_quantify_round_trip(tmp_path):
    rec = tmp_path / "lab.h5"
    r = run(
        "synth", "lab-ch4-5slpm-gf320", "-o", str(rec), "--duration", "1.5", "--seed", "2", "-q"
    )
    assert r.returncode == 0, r.stderr
    out = tmp_path / "out.json"
    r = run(
        "quantify",
        str(rec),
        "--surface",
        "100,200,220,200",
        "--species",
        "CH4",
        "--source",
        "159.5,227",
        "--json",
        str(out),
        "--csv",
        str(tmp_path / "out.csv"),
        "-q",
    )
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    s = d["surfaces"][0]
    assert s["points"] == [[100.0, 200.0], [220.0, 200.0]]
    sp = s["species"]["CH4"]
    for key in ("mean_kg_h", "ci90_kg_h", "n_frames", "time_s", "rate_kg_h", "truth_kg_h"):
        assert key in sp
    assert sp["n_frames"] == len(sp["time_s"]) == 23  # 1.5 s at 15 Hz, frames at 0 .. 1.47 s
    assert sp["mean_kg_h"] > 0
    assert "kg/h" in r.stdout


def test_quantify_reports_bad_input_clearly(tmp_path):
    r = run("quantify", str(tmp_path / "missing.h5"), "--surface", "1,2,3,4")
    assert r.returncode == 2 and "error" in r.stderr
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not hdf5")
    r = run("quantify", str(bad), "--surface", "1,2,3,4")
    assert r.returncode == 3 and "HDF5" in r.stderr  # bad data
