"""NETD noise: the measured noise, converted back to temperature, is the NETD."""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi.physics.camera import add_netd_noise, netd_radiance_sigma


@pytest.fixture(scope="module")
def camera():
    cam = qogi.camera_preset("fast-m150")
    assert cam.netd_K == 0.017
    return cam


def slope(ch, t, h=0.01):
    """dL/dT by central differences (independent of the engine's derivative)."""
    return (ch.band_radiance(t + h) - ch.band_radiance(t - h)) / (2 * h)


def test_sigma_is_netd_times_band_slope(camera):
    t_bg = [280.0, 288.15, 300.0, 320.0]
    sigma = netd_radiance_sigma(camera, background_temperature_K=t_bg)
    expected = [0.017 * slope(ch, t) for ch, t in zip(camera.channels, t_bg)]
    np.testing.assert_allclose(sigma, expected, rtol=1e-7)
    np.testing.assert_allclose(
        netd_radiance_sigma(camera.channels, [0.01, 0.02, 0.03, 0.04], 300),
        [n * slope(ch, 300.0) for n, ch in zip([0.01, 0.02, 0.03, 0.04], camera.channels)],
        rtol=1e-7,
    )
    with pytest.raises(ValueError, match="netd_K"):
        netd_radiance_sigma(camera.channels, None)
    with pytest.raises(ValueError, match="one per channel"):
        netd_radiance_sigma(camera, [0.01, 0.02])


def test_measured_noise_through_dl_dt_is_the_netd(camera):
    t_bg = np.array([288.15, 288.15, 295.0, 300.0])
    lum = np.array([ch.band_radiance(t) for ch, t in zip(camera.channels, t_bg)])
    n_frames, h, w = 16, 256, 256  # 2**20 values per channel
    frames = np.broadcast_to(lum[None, :, None, None], (n_frames, 4, h, w)).astype(np.float32)
    noisy = add_netd_noise(frames, camera, background_temperature_K=t_bg, seed=42)
    assert noisy.dtype == np.float32 and noisy.shape == frames.shape
    n = n_frames * h * w
    for c, ch in enumerate(camera.channels):
        d = (noisy[:, c].astype(np.float64) - float(frames[0, c, 0, 0])).ravel()
        netd = np.std(d) / slope(ch, t_bg[c])
        # Standard error of a standard deviation: sigma / sqrt(2 n); 5 of them.
        assert netd == pytest.approx(0.017, rel=5 / np.sqrt(2 * n)), ch.name
        assert abs(np.mean(d)) < 5 * np.std(d) / np.sqrt(n)
        # Gaussian: fraction within one sigma.
        p1 = 0.6826894921370859
        frac = np.mean(np.abs(d) < np.std(d))
        assert frac == pytest.approx(p1, abs=5 * np.sqrt(p1 * (1 - p1) / n))


def test_noise_is_seeded_and_reproducible(camera):
    frames = np.zeros((3, 4, 17, 23), np.float32)
    a = add_netd_noise(frames, camera, seed=7)
    b = add_netd_noise(frames, camera, seed=7, num_threads=1)
    c = add_netd_noise(frames, camera, seed=8)
    np.testing.assert_array_equal(a, b)
    assert np.all(frames == 0)  # input untouched
    assert abs(np.corrcoef(a.ravel(), c.ravel())[0, 1]) < 5 / np.sqrt(a.size)
    # Frame by frame with the stream offset: the same noise.
    pieces = np.concatenate(
        [
            add_netd_noise(frames[k : k + 1], camera, seed=7, offset=k * frames[0].size)
            for k in range(3)
        ]
    )
    np.testing.assert_array_equal(pieces, a)
    # In place.
    inplace = frames.copy()
    out = add_netd_noise(inplace, camera, seed=7, in_place=True)
    assert out is inplace
    np.testing.assert_array_equal(inplace, a)
    # The draws are the public stream times sigma.
    sigma = netd_radiance_sigma(camera)
    i = 5 * 17 * 23 + 11  # frame 1, channel 1
    ch = (i // (17 * 23)) % 4
    assert ch == 1
    assert a.ravel()[i] == np.float32(sigma[ch] * qogi._engine.standard_normal_draw(7, i))


def test_bad_noise_input(camera):
    with pytest.raises(ValueError, match="C = 4 channels"):
        add_netd_noise(np.zeros((2, 3, 5, 5), np.float32), camera, seed=1)
    with pytest.raises(ValueError, match="in_place"):
        add_netd_noise(np.zeros((1, 4, 5, 5)), camera, seed=1, in_place=True)
    with pytest.raises(ValueError, match="seed"):
        add_netd_noise(np.zeros((1, 4, 5, 5), np.float32), camera, seed=-1)
