"""`qogi info`: text and JSON output, statistics checked against the engine."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import qogi


def run(*args, check=True):
    return subprocess.run(
        [sys.executable, "-m", "qogi", "info", *map(str, args)],
        capture_output=True,
        text=True,
        check=check,
    )


@pytest.fixture
def rec_file(tmp_path):
    nu = np.linspace(2900.0, 3160.0, 27)
    chs = [
        qogi.SpectralResponse(nu, np.exp(-(((nu - 3030.0) / 80.0) ** 6)), "CH4 filter"),
        qogi.SpectralResponse([1852.0, 6667.0], [1.0, 1.0], "open InSb"),
    ]
    f = np.random.default_rng(5).uniform(285.0, 310.0, (9, 2, 6, 7)).astype(np.float32)
    rec = qogi.Recording.from_arrays(
        f,
        quantity="radiometric_temperature",
        camera=qogi.Camera("GF-test", 2e-3, chs, 15.0, netd_K=0.015),
        scene=qogi.Scene(8.0, 291.0, 99000.0, wind_speed_m_s=1.5, species=("CH4",)),
        truth=qogi.Truth({"CH4": 1e-4}),
    )
    p = tmp_path / "rec.h5"
    rec.save(p)
    return p, f, chs


def test_text_output_lists_everything(rec_file):
    p, f, chs = rec_file
    out = run(p).stdout
    for text in (
        "GF-test",
        "CH4 filter",
        "open InSb",
        "T=9 C=2 H=6 W=7",
        "radiometric_temperature [K]",
        "15 Hz",
        "distance 8 m",
        "pressure 99000 Pa",
        "species CH4",
        "CH4 0.0001 kg/s (0.36 kg/h)",
        "centroid",
        "half max",
    ):
        assert text in out, text


def test_json_statistics_match_the_exact_engine(rec_file):
    p, f, chs = rec_file
    info = json.loads(run(p, "--json").stdout)
    assert info["frames"]["T"] == 9 and info["frames"]["duration_s"] == pytest.approx(9 / 15.0)
    assert info["truth"]["emission_rate_kg_h"]["CH4"] == pytest.approx(0.36)
    for k, ch in enumerate(chs):
        c = info["first_frame"][k]
        t0 = f[0, k].astype(np.float64)
        lum = ch.band_radiance(t0)
        assert c["radiometric_temperature_K"]["min"] == pytest.approx(t0.min(), abs=1e-6)
        assert c["radiometric_temperature_K"]["mean"] == pytest.approx(t0.mean(), abs=1e-6)
        assert c["radiance_W_m2_sr"]["max"] == pytest.approx(lum.max(), rel=1e-6)
        assert c["radiance_W_m2_sr"]["mean"] == pytest.approx(lum.mean(), rel=1e-6)
        assert info["channels"][k]["centroid_cm1"] == pytest.approx(ch.centroid_cm1)
    lo, hi = info["channels"][0]["half_max_cm1"]
    # exp(-(d/80)^6) = 1/2 at d = 80 ln(2)^(1/6); the samples are 10 cm-1 apart.
    half = 80.0 * np.log(2.0) ** (1 / 6)
    assert lo == pytest.approx(3030.0 - half, abs=2.0) and hi == pytest.approx(
        3030.0 + half, abs=2.0
    )


def test_bad_file_gives_a_clear_error_and_exit_code(tmp_path):
    p = tmp_path / "broken.h5"
    p.write_text("not hdf5")
    r = run(p, check=False)
    assert r.returncode == 3  # bad data (a missing file is a usage error, 2)
    assert "broken.h5" in r.stderr and "not an HDF5 file" in r.stderr
    r = run(tmp_path / "missing.h5", check=False)
    assert r.returncode == 2 and "missing.h5" in r.stderr


def test_flir_file_info(shared_dir):
    info = json.loads(run(shared_dir / "samples" / "flir" / "SampleSEQ.seq", "--json").stdout)
    assert info["n_frames"] == 2 and info["metadata"]["camera_model"] == "FLIR SC660"
    assert info["metadata"]["planck_b"] == 1501.0
    assert info["time_span_s"] == pytest.approx(3.967, abs=1e-3)
