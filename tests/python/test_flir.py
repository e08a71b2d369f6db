"""FLIR readers on the shared sample files (third-party, found beside the checkout
or in $QOGI_SHARED_DIR; from the Thermimage R package), checked against values
published in Thermimage's README for these very files, against CharLS's decoding
of the .csq frames (tests/data/flir/csq_reference.json), and against physics."""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

import qogi
import qogi.io as qio
from qogi import _engine

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture(scope="module")
def flir_dir(shared_dir):
    d = shared_dir / "samples" / "flir"
    if not d.is_dir():
        pytest.fail(f"FLIR samples not found in {d}")
    return d


def lwir():
    return qogi.SpectralResponse.from_wavelength_um([7.5, 13.0], [1.0, 1.0], "LWIR 7.5-13 um")


# ------------------------------------------------------------------ JPEG-LS


@pytest.mark.parametrize("name", sorted(p.stem for p in (DATA / "jpegls").glob("*.jls")))
def test_jpegls_matches_charls(name):
    code = (DATA / "jpegls" / f"{name}.jls").read_bytes()
    expected = np.load(DATA / "jpegls" / f"{name}.npy")
    samples, info = _engine.decode_jpegls(code)
    assert samples.shape == expected.shape
    np.testing.assert_array_equal(samples.astype(np.uint16), expected.astype(np.uint16))


def test_jpegls_rejects_garbage_with_a_clear_error():
    with pytest.raises(ValueError, match="JPEG-LS: not a JPEG-LS codestream"):
        _engine.decode_jpegls(b"not an image")


# ------------------------------------------------------------------ .seq


def test_seq_frames_dimensions_and_raw_counts(flir_dir):
    frames = qio.read_flir(flir_dir / "SampleSEQ.seq")
    assert len(frames) == 2
    for fr in frames:
        assert fr.raw.shape == (480, 640) and fr.raw.dtype == np.uint16
    # Thermimage README, `head(alldata)`: the first six counts of frame 1.
    np.testing.assert_array_equal(frames[0].raw[0, :6], [17870, 17833, 17808, 17829, 17829, 17861])


def test_seq_metadata(flir_dir):
    with qio.open_flir(flir_dir / "SampleSEQ.seq") as f:
        m = f.metadata(0)
        m1 = f.metadata(1)
    assert m.camera_model == "FLIR SC660" and m.lens_model == "FOL38"
    assert m.width == 640 and m.height == 480 and m.raw_format == "raw-le"
    # Thermimage README: the SC660 constants.
    assert m.planck_r1 == pytest.approx(21106.77, abs=0.01)
    assert m.planck_b == 1501.0 and m.planck_f == 1.0 and m.planck_o == -7340.0
    assert m.planck_r2 == pytest.approx(0.012545258, rel=1e-7)
    assert m.emissivity == pytest.approx(0.95) and m.object_distance_m == pytest.approx(1.0)
    assert m.reflected_temperature_K == pytest.approx(293.15, abs=1e-4)
    assert m.atmospheric_temperature_K == pytest.approx(293.15, abs=1e-4)
    assert m.relative_humidity == pytest.approx(0.5)
    assert m.atmospheric_trans_alpha1 == pytest.approx(0.006569, rel=1e-6)
    assert m.atmospheric_trans_x == pytest.approx(1.9)
    assert m.frame_rate_hz == 30
    # Thermimage README getTimes: 2012-06-13 15:52:08.698 and 15:52:12.665 US Eastern
    # daylight time, i.e. 19:52:08.7 UTC, 3.967 s apart.
    utc = dt.datetime.fromtimestamp(m.timestamp_s, dt.timezone.utc)
    assert utc.replace(microsecond=0) == dt.datetime(2012, 6, 13, 19, 52, 8, tzinfo=dt.timezone.utc)
    assert m1.timestamp_s - m.timestamp_s == pytest.approx(3.967, abs=1e-3)
    # The camera calibration's effective wavelength (ExifTool: 14387.65 / B um, an
    # older c2 than CODATA 2018's 14387.769 um K, hence rel 2e-5).
    assert 1e4 / m.effective_wavenumber_cm1 == pytest.approx(14387.6515 / 1501.0, rel=2e-5)


def test_seq_temperatures_match_thermimage(flir_dir):
    fr = qio.read_flir(flir_dir / "SampleSEQ.seq")[0]
    # Thermimage README: raw2temp with the file's settings, `head(alltemperature)`.
    expected_c = [22.46279, 22.24723, 22.10131, 22.22390, 22.22390, 22.41040]
    np.testing.assert_allclose(fr.temperature()[0, :6] - 273.15, expected_c, atol=1e-5)
    # ... and its lookup table entries templookup[c(17172, 18273, 24932) - 1].
    np.testing.assert_allclose(
        qio.flir_temperature(np.array([17171, 18272, 24931]), fr.metadata) - 273.15,
        [18.30355, 24.77367, 57.07398],
        atol=1e-5,
    )


def test_temp2raw_and_raw2temp_readme_example(flir_dir):
    m = qio.read_flir(flir_dir / "SampleSEQ.seq")[0].metadata
    m = dataclasses.replace(
        m,
        planck_r1=21106.77,
        planck_b=1501.0,
        planck_f=1.0,
        planck_o=-7340.0,
        planck_r2=0.012545258,
    )
    common = dict(
        reflected_temperature_K=293.15,
        atmospheric_temperature_K=293.15,
        ir_window_temperature_K=293.15,
        relative_humidity=0.5,
    )
    # Thermimage README: temp2raw(23, E=1, OD=0, ...) = 17994.06 and
    # raw2temp(17994.06, E=0.95, OD=1, IRT=0.96, ...) = 23.31223.
    raw = qio.flir_raw_from_temperature(
        296.15, m, emissivity=1.0, object_distance_m=0.0, ir_window_transmission=1.0, **common
    )
    assert raw == pytest.approx(17994.06, abs=0.005)
    t = qio.flir_temperature(
        17994.06, m, emissivity=0.95, object_distance_m=1.0, ir_window_transmission=0.96, **common
    )
    assert t - 273.15 == pytest.approx(23.31223, abs=1e-5)


def test_blackbody_limit_is_the_planck_calibration(flir_dir):
    m = qio.read_flir(flir_dir / "SampleSEQ.seq")[0].metadata
    t = np.array([260.0, 300.0, 350.0, 400.0])
    raw = m.planck_r1 / (m.planck_r2 * (np.exp(m.planck_b / t) - m.planck_f)) - m.planck_o
    np.testing.assert_allclose(qio.flir_apparent_temperature(raw, m), t, rtol=1e-12)
    # E = 1, no path, no window: object temperature = apparent temperature.
    np.testing.assert_allclose(
        qio.flir_temperature(
            raw, m, emissivity=1.0, object_distance_m=0.0, ir_window_transmission=1.0
        ),
        t,
        rtol=1e-12,
    )
    # A surface at the reflected temperature reads that temperature at any emissivity.
    raw_refl = qio.flir_raw_from_temperature(
        m.reflected_temperature_K, m, emissivity=1.0, object_distance_m=0.0
    )
    assert qio.flir_temperature(
        raw_refl, m, emissivity=0.3, object_distance_m=0.0
    ) == pytest.approx(m.reflected_temperature_K, rel=1e-12)


# ------------------------------------------------------------------ .csq


def test_csq_frames_are_charls_bit_exact(flir_dir):
    ref = json.loads((DATA / "flir" / "csq_reference.json").read_text())["frames"]
    with qio.open_flir(flir_dir / "SampleCSQ.csq") as f:
        assert len(f) == len(ref) == 8
        for r in ref:
            fr = f.frame(r["index"])
            assert list(fr.raw.shape) == r["shape"] == [768, 1024]
            assert (
                hashlib.sha256(fr.raw.astype("<u2").tobytes()).hexdigest() == r["sha256_uint16_le"]
            )
            for y, x, v in r["pixels_yx"]:
                assert fr.raw[y, x] == v
            assert fr.metadata.raw_format == "jpegls"


def test_csq_metadata_and_coding(flir_dir):
    with qio.open_flir(flir_dir / "SampleCSQ.csq") as f:
        metas = [f.frame(i).metadata for i in range(len(f))]
    m = metas[0]
    assert m.camera_model.startswith("FLIR T1030sc") and m.lens_model == "FOL83"
    assert (m.width, m.height) == (1024, 768)
    assert m.planck_o == -6331.0 and m.planck_b == pytest.approx(1507.2, abs=1e-4)
    assert m.raw_value_range_min == 7460 and m.raw_value_range_max == 55816
    # FLIR codes these frames near-lossless, with a per-frame error bound.
    assert [mm.jpegls_near for mm in metas] == [5, 5, 20, 20, 16, 17, 14, 15]
    dts = np.diff([mm.timestamp_s for mm in metas])
    np.testing.assert_allclose(dts, 1 / 30, atol=1.5e-3)  # ms time stamps of a 30 Hz video


# ------------------------------------------------------------------ radiometric JPEG


def test_radiometric_jpeg(flir_dir):
    frames = qio.read_flir(flir_dir / "IR_2412.jpg")
    assert len(frames) == 1
    fr = frames[0]
    assert fr.raw.shape == (480, 640)
    # Thermimage README: str(img) lists the first column of the 480 x 640 image.
    np.testing.assert_array_equal(
        fr.raw[:10, 0], [18090, 18074, 18064, 18061, 18081, 18057, 18092, 18079, 18071, 18071]
    )
    # ... and str(temperature) the converted values, printed to 3 digits.
    np.testing.assert_allclose(
        fr.temperature()[:5, 0] - 273.15, [23.7, 23.6, 23.6, 23.6, 23.7], atol=0.05
    )
    m = fr.metadata
    assert m.planck_r1 == pytest.approx(21106.77, abs=0.01) and m.planck_o == -7340.0
    assert m.camera_model == "FLIR SC660"
    # Thermimage README: DateTimeOriginal 2013-05-09 22:22:23 (US Eastern daylight time).
    utc = dt.datetime.fromtimestamp(m.timestamp_s, dt.timezone.utc).replace(microsecond=0)
    assert utc == dt.datetime(2013, 5, 10, 2, 22, 23, tzinfo=dt.timezone.utc)


def test_not_a_flir_file(tmp_path):
    p = tmp_path / "x.seq"
    p.write_bytes(b"hello world, not FLIR")
    with pytest.raises(ValueError, match=r"x.seq: not a FLIR radiometric file"):
        qio.read_flir(p)
    import cv2

    ok, jpg = cv2.imencode(".jpg", np.zeros((8, 8), np.uint8))
    q = tmp_path / "plain.jpg"
    q.write_bytes(jpg.tobytes())
    with pytest.raises(ValueError, match=r"plain.jpg: a JPEG without FLIR radiometric data"):
        qio.read_flir(q)


# ------------------------------------------------------------------ -> Recording


def test_flir_to_recording_needs_a_channel(flir_dir):
    with pytest.raises(
        qogi.RecordingError,
        match=r"SampleSEQ.seq: channel: a FLIR file stores raw counts.*"
        r"spectral response.*Fix: pass channel=",
    ):
        qio.read_flir_recording(flir_dir / "SampleSEQ.seq", pressure_Pa=101325.0)


def test_flir_to_recording_needs_the_pressure(flir_dir):
    with pytest.raises(qogi.RecordingError, match=r"pressure_Pa.*Fix: pass pressure_Pa"):
        qio.read_flir_recording(flir_dir / "SampleSEQ.seq", channel=lwir())


def test_flir_to_recording_warns_about_a_foreign_band(flir_dir):
    mwir = qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], "3.2-3.4 um")
    with pytest.warns(UserWarning, match="calibration .* implies 1043 cm-1"):
        qio.read_flir_recording(flir_dir / "SampleSEQ.seq", channel=mwir, pressure_Pa=101325.0)


@pytest.mark.parametrize(
    "name,n,rate",
    [("SampleSEQ.seq", 2, 1 / 3.967), ("SampleCSQ.csq", 8, 30.0), ("IR_2412.jpg", 1, 30.0)],
)
def test_flir_to_recording(flir_dir, tmp_path, name, n, rate):
    csv = tmp_path / "lwir.csv"
    lwir().to_csv(csv)
    rec = qio.read_flir_recording(flir_dir / name, channel=str(csv), pressure_Pa=101325.0)
    assert rec.n_frames == n and rec.n_channels == 1
    assert rec.quantity == "radiometric_temperature"
    assert rec.camera.frame_rate_hz == pytest.approx(rate, rel=2e-3)
    assert rec.scene.distance_m == pytest.approx(1.0)
    assert rec.scene.ambient_temperature_K == pytest.approx(293.15, abs=1e-4)
    fr = qio.read_flir(flir_dir / name)[-1]
    np.testing.assert_allclose(rec.frame(-1)[0], fr.apparent_temperature(), rtol=1e-6)
    # IFOV from the lens field of view.
    assert rec.camera.ifov_rad == pytest.approx(
        np.deg2rad(fr.metadata.field_of_view_deg) / fr.metadata.width
    )
    # Band radiance through the named channel, checked against the exact engine.
    lum = rec.frame(0, quantity="radiance")[0]
    t0 = rec.frame(0)[0].astype(np.float64)
    np.testing.assert_allclose(lum[::37, ::41], lwir().band_radiance(t0[::37, ::41]), rtol=2e-7)
    out = tmp_path / "rec.h5"
    rec.save(out)
    back = qogi.open_recording(out)
    np.testing.assert_array_equal(back.frame(0), rec.frame(0))
    assert back.attrs["flir_temperature"] == "apparent"


def test_object_parameters_option(flir_dir):
    rec = qio.read_flir_recording(
        flir_dir / "SampleSEQ.seq", channel=lwir(), pressure_Pa=101325.0, object_parameters=True
    )
    # float32 storage: half an ulp at 295 K is 1.5e-5 K.
    np.testing.assert_allclose(
        rec.frame(0)[0, 0, :6].astype(np.float64) - 273.15,
        [22.46279, 22.24723, 22.10131, 22.22390, 22.22390, 22.41040],
        atol=2.5e-5,
    )
