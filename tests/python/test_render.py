"""The synthetic camera: rendering checks, the fast model on real simulated
(non-Gaussian) lines of sight against the exact one, and the recording file
contract read with plain h5py."""

import dataclasses
import subprocess
import sys

import h5py
import numpy as np
import pytest

import qogi
from qogi import synth
from qogi.synth import render


def small_scene(exit_K=294.0, ambient_K=294.0, rate_slpm=5.0):
    release = synth.Release(
        rate=rate_slpm,
        rate_unit="SLPM",
        composition={"CH4": 1.0},
        exit_diameter_m=0.019,
        exit_temperature_K=exit_K,
        ambient_temperature_K=ambient_K,
        draft_m_s=0.02,
    )
    cam = qogi.camera_preset("gf320")
    cam = dataclasses.replace(cam, width=64, height=48, ifov_rad=4 * cam.ifov_rad)
    view = synth.View.framing(
        release, (31.5, 44.0), width_px=64, height_px=48, ifov_rad=cam.ifov_rad, distance_m=1.5
    )
    sim = synth.simulate(release, view, duration_s=0.6, frame_rate_hz=15.0, seed=3)
    return sim, cam


def test_gas_at_the_background_temperature_renders_no_contrast(tmp_path):
    sim, cam = small_scene(exit_K=290.0, ambient_K=290.0)
    r = render.SceneRenderer(sim, cam, render.Background("plate", 290.0), training_rays=300)
    frame = r.render_frame(5)
    bg = r.background_radiance()
    assert sim.column_density(5)["CH4"].max() > 1e-4  # there is gas in view
    np.testing.assert_allclose(frame, np.broadcast_to(bg, frame.shape), rtol=2e-6)


def test_outside_the_plume_the_background_and_the_stated_netd(tmp_path):
    sim, cam = small_scene()
    path = render.render_recording(
        sim, cam, render.Background("plate", 285.15), tmp_path / "r.h5", seed=7
    )
    rec = qogi.open_recording(path)
    frames = rec.to_array()[:, 0]  # (T, H, W) radiance
    cols = np.stack([sim.column_density(f)["CH4"] for f in range(sim.num_frames)])
    clear = cols == 0
    assert clear.sum() > 10000
    ch = rec.channels[0]
    bg = ch.band_radiance(285.15)
    values = frames[clear]
    # Mean: the background, to a few standard errors of the noise.
    sigma_l = 0.015 * ch.band_radiance_derivative(285.15)
    assert abs(values.mean() - bg) < 5 * sigma_l / np.sqrt(values.size)
    # Spread: NETD x dL/dT within the sampling error (a few percent here).
    assert values.std() / sigma_l == pytest.approx(1.0, abs=0.04)
    # And where there is gas, warm methane in front of a colder plate glows.
    assert frames[cols > 1e-3].mean() > bg + 5 * sigma_l
    # The renderer's own accuracy against the full fast model is recorded.
    err = rec.truth.attrs[f"render_contrast_error_max_{ch.name}"]
    assert err < 1e-3


def test_fast_model_on_simulated_lines_of_sight_agrees_with_exact():
    sim, cam = small_scene(exit_K=330.0, ambient_K=295.0)
    fm = qogi.ForwardModel(cam, ["CH4"])
    s = sim.ray_samples(4)
    counts = np.diff(s["offset"])
    gas = np.flatnonzero(counts > 2)
    col = np.array(
        [
            s["mole_fraction"]["CH4"][s["offset"][i] : s["offset"][i + 1]].sum()
            * s["path_m"].ravel()[i]
            for i in gas
        ]
    )
    picks = gas[np.argsort(col)[np.linspace(0, len(gas) - 1, 6).astype(int)]]
    worst = 0.0
    for pos, t, x in render._paths_from_samples(s, ["CH4"], 295.0, picks):
        le = fm.band_radiance_path(pos, t, x, 285.0, exact=True)
        lf = fm.band_radiance_path(pos, t, x, 285.0)
        bg = fm.background_radiance(285.0)
        worst = max(worst, float(np.max(np.abs(lf - le) / np.maximum(np.abs(le - bg), 1e-4 * bg))))
    assert worst < 0.01


def test_cli_recording_follows_the_contract_read_with_plain_h5py(tmp_path):
    out = tmp_path / "lab.h5"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "qogi",
            "synth",
            "lab-ch4-5slpm-gf320",
            "-o",
            str(out),
            "--duration",
            "0.4",
            "--seed",
            "1",
            "-q",
        ],
        check=True,
    )
    with h5py.File(out, "r") as f:
        assert f.attrs["format"] == b"qogi-recording" and int(f.attrs["version"]) == 1
        frames = f["frames"]
        assert frames.dtype == np.float32 and frames.ndim == 4
        t, c, h, w = frames.shape
        assert (c, h, w) == (1, 240, 320) and t == 6
        assert frames.attrs["quantity"] == b"radiance"
        assert f["time_s"].shape == (t,) and f["time_s"].dtype == np.float64
        cam = f["camera"]
        for key in ("name", "ifov_rad", "frame_rate_hz"):
            assert key in cam.attrs
        ch = cam["channels"]["0"]
        assert ch["wavenumber_cm1"].shape == ch["response"].shape
        assert "name" in ch.attrs
        for key in ("distance_m", "ambient_temperature_K", "pressure_Pa"):
            assert key in f["scene"].attrs
        rate = f["truth"].attrs["emission_rate_kg_s_CH4"]
        # 5 SLPM of CH4 at 20 C, 1 atm: 5e-3/60 m3/s x 0.6669 kg/m3.
        assert rate == pytest.approx(
            5e-3 / 60 * 101325 * 16.0425e-3 / (8.314462618 * 293.15), rel=1e-4
        )
        assert np.all(np.isfinite(frames[:]))
