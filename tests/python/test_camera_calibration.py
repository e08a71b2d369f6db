"""Radiometric calibration against a synthetic camera with known truth."""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi.physics.camera import Calibration, CalibrationScene, fit_calibration

H, W = 16, 20


def channels():
    nu = np.arange(2000.0, 3400.0, 2.0)

    def band(lo, hi):  # smooth band-pass between lo and hi cm-1
        return 1.0 / (1.0 + np.exp(-(nu - lo) / 6.0)) / (1.0 + np.exp((nu - hi) / 6.0))

    return [
        qogi.SpectralResponse(nu, 0.8 * band(2950.0, 3150.0), "CH4"),
        qogi.SpectralResponse(nu, 0.8 * band(2220.0, 2400.0), "CO2"),
    ]


class Camera:
    """Pixel p of channel c reads round(t (g_cp L + o_cp)) counts (uint16)."""

    def __init__(self, chans, seed=1):
        rng = np.random.default_rng(seed)
        self.chans = chans
        # ~30 000 counts at 360 K and 1 ms in each channel.
        l360 = np.array([ch.band_radiance(360.0) for ch in chans])
        self.g = (2.7e7 / l360)[:, None, None] * (1 + 0.05 * rng.standard_normal((2, H, W)))
        self.o = 3.0e6 * (1 + 0.1 * rng.standard_normal((2, H, W)))
        self.noise = 0.0
        self.rng = np.random.default_rng(seed + 100)

    def radiance(self, t_k):
        return np.array([ch.band_radiance(t_k) for ch in self.chans])

    def frames(self, radiance, t_int, n):
        """radiance (C,) or (n, C); t_int scalar, (C,) or (n, C) -> (n, C, H, W) uint16."""
        lum = np.broadcast_to(np.asarray(radiance, float), (n, 2))[..., None, None]
        t = np.broadcast_to(np.asarray(t_int, float), (n, 2))[..., None, None]
        c = t * (self.g * lum + self.o)
        c = c + self.noise * self.rng.standard_normal(c.shape)
        return np.clip(np.round(c), 0, 65535).astype(np.uint16)


TEMPS = [283.0, 303.0, 323.0, 343.0, 363.0]


def scenes(cam, temps=TEMPS, t_int=1e-3, n=6):
    return [CalibrationScene(t, cam.frames(cam.radiance(t), t_int, n), t_int) for t in temps]


@pytest.fixture(scope="module")
def fitted():
    cam = Camera(channels())
    cam.noise = 2.0
    return cam, fit_calibration(scenes(cam), cam.chans)


def test_raw_uint16_stacks_calibrate_to_the_true_radiance(fitted):
    cam, cal = fitted
    assert cal.num_channels == 2 and cal.frame_shape == (H, W)
    # A stack of 3 frames at other temperatures, per-frame and per-channel times.
    temps = np.array([293.0, 313.0, 353.0])
    t_int = np.array([[1e-3, 5e-4], [2e-3, 1e-3], [5e-4, 5e-4]])
    truth = np.stack([cam.radiance(t) for t in temps])  # (3, C)
    raw = cam.frames(truth, t_int, 3)  # (3, C, H, W) uint16
    lum = cal.counts_to_radiance(raw, t_int)
    assert lum.dtype == np.float32 and lum.shape == raw.shape
    # Error budget per pixel, in counts at the test frame's time t: the NUC
    # scene means (6 frames at 1 ms) carry sqrt((2^2 + 1/12) / 6) counts,
    # scaled by t / 1 ms; the test frame its own 2 counts of noise and 1/12
    # counts^2 of rounding. Through dcounts/dL = t g.
    t_full = t_int[:, :, None, None]
    var_nuc = (4.0 + 1 / 12) / 6 * (t_full / 1e-3) ** 2
    sigma_l = np.sqrt(var_nuc + 4.0 + 1 / 12) / (t_full * cam.g)
    z = (lum - truth[..., None, None]) / sigma_l
    assert np.max(np.abs(z)) < 6
    assert 0.5 < np.std(z) < 1.2
    # Radiometric temperature.
    temp = cal.apply(raw, t_int, quantity="radiometric_temperature")
    sigma_t = (
        sigma_l
        / np.stack([np.array([ch.band_radiance_derivative(t) for ch in cam.chans]) for t in temps])[
            ..., None, None
        ]
    )
    assert np.max(np.abs(temp - temps[:, None, None, None]) / sigma_t) < 6
    assert cal.last_stats == {"out_of_range": 0, "replaced": 0, "unreplaced": 0}


def test_counts_round_trip_and_single_frames(fitted):
    cam, cal = fitted
    lum = np.broadcast_to(cam.radiance(318.0)[:, None, None], (2, H, W)).astype(np.float32)
    counts = cal.radiance_to_counts(lum, [1e-3, 2e-3])  # one (C, H, W) frame
    assert counts.shape == (2, H, W)
    back = cal.counts_to_radiance(counts, [1e-3, 2e-3])
    np.testing.assert_allclose(back, lum, rtol=2e-6)
    with pytest.raises(ValueError, match="2 channels"):
        cal.counts_to_radiance(np.zeros((3, H, W), np.float32), 1e-3)
    with pytest.raises(ValueError, match="pixels"):
        cal.counts_to_radiance(np.zeros((2, H, W + 1), np.float32), 1e-3)
    with pytest.raises(ValueError, match="integration_time_s"):
        cal.counts_to_radiance(counts, [1e-3, -1.0])
    with pytest.raises(ValueError, match="integration_time_s"):
        cal.counts_to_radiance(counts, [1e-3, 1e-3, 1e-3])
    with pytest.raises(ValueError, match="quantity"):
        cal.apply(counts, 1e-3, quantity="counts")


def test_fit_diagnostics(fitted):
    cam, cal = fitted
    for c, ch in enumerate(cal.channels):
        p = ch.points
        np.testing.assert_allclose(p["blackbody_temperature_K"], TEMPS)
        np.testing.assert_allclose(
            p["radiance"], [cam.chans[c].band_radiance(t) for t in TEMPS], rtol=1e-12
        )
        # Truth is linear: residuals are noise (scene means of 6 x 320 draws
        # of 2 counts, ~0.05 counts), far below 1 mK.
        assert ch.rms_residual_K < 1e-3
        assert ch.num_bad_pixels == 0
        assert ch.curve.gain == pytest.approx(np.mean(cam.g[c]), rel=1e-3)
    text = cal.report()
    assert "rms residual" in text and "363.00" in text and "'CO2'" in text
    assert "2 channels" in repr(cal)


def test_single_channel_camera_and_per_frame_times():
    chans = channels()[:1]
    cam = Camera(channels())
    one = [CalibrationScene(t, cam.frames(cam.radiance(t), 1e-3, 4)[:, 0], 1e-3) for t in TEMPS]
    cal = fit_calibration(one, chans)
    truth = cam.radiance(330.0)[0]
    raw = cam.frames(cam.radiance(330.0), [[1e-3, 1e-3], [2e-3, 2e-3]], 2)[:, 0]  # (2, H, W)
    lum = cal.counts_to_radiance(raw, [1e-3, 2e-3])
    assert lum.shape == (2, H, W)
    # Noise-free frames: only count rounding (0.29 counts rms) remains.
    assert np.max(np.abs(lum / truth - 1)) < 2e-4


@pytest.mark.parametrize("kind", ["npz", "h5", "group"])
def test_save_and_load_round_trip(fitted, tmp_path, kind):
    import h5py

    cam, cal = fitted
    raw = cam.frames(cam.radiance(320.0), 1e-3, 2)
    if kind == "npz":
        cal.save(tmp_path / "cal.npz")
        back = Calibration.load(tmp_path / "cal.npz")
    elif kind == "h5":
        cal.save(tmp_path / "cal.h5")
        cal.save(tmp_path / "cal.h5")  # replaces the group
        back = Calibration.load(tmp_path / "cal.h5")
    else:
        with h5py.File(tmp_path / "rec.h5", "w") as f:
            cal.save(f.create_group("camera"), group="calibration")
        with h5py.File(tmp_path / "rec.h5", "r") as f:
            back = Calibration.load(f["camera"])
    np.testing.assert_array_equal(
        back.counts_to_radiance(raw, 1e-3), cal.counts_to_radiance(raw, 1e-3)
    )
    assert [r.name for r in back.responses] == ["CH4", "CO2"]
    np.testing.assert_array_equal(
        back.channels[1].points["residual_K"], cal.channels[1].points["residual_K"]
    )


def test_loading_something_else_is_refused(tmp_path):
    np.savez(tmp_path / "x.npz", format=np.array("something"), version=np.array(1))
    with pytest.raises(ValueError, match="not a qogi calibration"):
        Calibration.load(tmp_path / "x.npz")
    np.savez(tmp_path / "y.npz", a=np.zeros(3))
    with pytest.raises(ValueError, match="missing"):
        Calibration.load(tmp_path / "y.npz")
    import h5py

    with h5py.File(tmp_path / "z.h5", "w"):
        pass
    with pytest.raises(ValueError, match="no calibration group"):
        Calibration.load(tmp_path / "z.h5")


def test_bad_pixels_are_replaced():
    cam = Camera(channels(), seed=4)
    cam.noise = 1.0
    cam.g[0, 3, 4] = 0.0  # dead in channel 0
    cam.o[1, 10, 10] = 8e7  # saturating in channel 1
    cal = fit_calibration(scenes(cam), cam.chans)
    assert np.argwhere(cal.channels[0].bad_pixels).tolist() == [[3, 4]]
    assert np.argwhere(cal.channels[1].bad_pixels).tolist() == [[10, 10]]
    raw = cam.frames(cam.radiance(300.0), 1e-3, 1)
    lum = cal.counts_to_radiance(raw, 1e-3)
    assert cal.last_stats["replaced"] == 2
    neighbours = np.delete(lum[0, 0, 2:5, 3:6].ravel(), 4)
    assert lum[0, 0, 3, 4] == pytest.approx(np.mean(neighbours, dtype=np.float64), rel=1e-6)
    lum_nan = cal.counts_to_radiance(raw, 1e-3, replace_bad_pixels=False)
    assert np.isnan(lum_nan[0, 0, 3, 4]) and np.isnan(lum_nan[0, 1, 10, 10])


def test_bad_calibration_input_is_refused_clearly():
    cam = Camera(channels())
    good = scenes(cam, n=2)
    with pytest.raises(ValueError, match=r"channel 0 \('CH4'\): .*at least 3 distinct"):
        fit_calibration(good[:2], cam.chans)
    with pytest.raises(ValueError, match="at least 4 distinct"):
        fit_calibration(good[:3], cam.chans, quadratic=True)
    swapped = list(good)
    swapped[1], swapped[3] = (
        CalibrationScene(303.0, good[3].frames, 1e-3),
        CalibrationScene(343.0, good[1].frames, 1e-3),
    )
    with pytest.raises(ValueError, match="not monotonic"):
        fit_calibration(swapped, cam.chans)
    hot = Camera(channels())
    hot.g *= 3.0
    with pytest.raises(ValueError, match="saturated"):
        fit_calibration(scenes(hot, n=2), hot.chans)
    with pytest.raises(ValueError, match="share one frame size"):
        fit_calibration(
            good[:4] + [CalibrationScene(363.0, good[4].frames[..., :-1], 1e-3)], cam.chans
        )
    with pytest.raises(ValueError, match="C = 2 channels"):
        fit_calibration(
            [CalibrationScene(s.blackbody_temperature_K, s.frames[:, 0], 1e-3) for s in good],
            cam.chans,
        )
    with pytest.raises(ValueError, match="integration_time_s"):
        fit_calibration(good[:4] + [CalibrationScene(363.0, good[4].frames, 0.0)], cam.chans)
    with pytest.raises(ValueError, match="blackbody_emissivity"):
        fit_calibration(good, cam.chans, blackbody_emissivity=1.5)
    with pytest.raises(ValueError, match=r"no calibration scenes|needs calibration scenes"):
        fit_calibration([], cam.chans)
    with pytest.raises(TypeError, match="CalibrationScene"):
        fit_calibration([(300.0, good[0].frames, 1e-3)], cam.chans)


def test_quadratic_detector_needs_the_quadratic_term():
    cam = Camera(channels(), seed=9)
    kappa = 0.02  # 2 % nonlinearity at 360 K
    l360 = cam.radiance(360.0)

    def scene(t):
        lum = cam.radiance(t)
        return CalibrationScene(t, cam.frames(lum + kappa * lum**2 / l360, 1e-3, 4), 1e-3)

    sc = [scene(t) for t in TEMPS]
    lin = fit_calibration(sc, cam.chans)
    quad = fit_calibration(sc, cam.chans, quadratic=True)
    for c in range(2):
        assert lin.channels[c].rms_residual_K > 0.1
        assert quad.channels[c].rms_residual_K < 1e-3  # count rounding only
        q_true = np.mean(cam.g[c]) * kappa / l360[c]
        assert quad.channels[c].curve.quadratic == pytest.approx(q_true, rel=1e-2)


def test_options_mirror_the_engine_struct():
    o = qogi._engine.CalibrationOptions(quadratic=True, saturation_counts=16383.0)
    d = o.to_dict()
    assert d["quadratic"] is True and d["saturation_counts"] == 16383.0
    assert d["bad_response_tolerance"] == 0.3 and d["max_bad_fraction"] == 0.05
    assert "saturation_counts=16383.0" in repr(o)
    assert qogi._engine.CalibrationOptions(**d).to_dict() == d
    with pytest.raises(ValueError, match="bad_response_tolerance"):
        qogi._engine.CalibrationOptions(bad_response_tolerance=1.5)


def test_calibration_and_optics_pickle(fitted):
    import pickle

    cam, cal = fitted
    back = pickle.loads(pickle.dumps(cal))
    raw = cam.frames(cam.radiance(320.0), 1e-3, 1)
    np.testing.assert_array_equal(
        back.counts_to_radiance(raw, 1e-3), cal.counts_to_radiance(raw, 1e-3)
    )
    o = qogi.camera_optics("fast-m150")[1]
    o2 = pickle.loads(pickle.dumps(o))
    assert isinstance(o2, qogi.ChannelOptics)
    assert o2.warm_radiance(293.0, 294.0) == o.warm_radiance(293.0, 294.0)


def test_progress_reports_the_overall_fraction_and_can_cancel(fitted):
    cam, cal = fitted
    raw = cam.frames(cam.radiance(320.0), 1e-3, 64)
    seen = []
    cal.counts_to_radiance(raw, 1e-3, progress=seen.append)
    assert seen and seen[-1] == pytest.approx(1.0) and max(seen) <= 1.0 + 1e-12
    assert all(b >= a for a, b in zip(seen, seen[1:]))
    with pytest.raises(qogi.Cancelled):
        cal.counts_to_radiance(raw, 1e-3, progress=lambda f: False)
