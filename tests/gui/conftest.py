"""Fixtures for the viewer's tests: a per-test user store and small recordings
whose frames are blackbody radiances of known temperatures (exact truth)."""

from __future__ import annotations

import numpy as np
import pytest

import qogi

W, H, T, RATE_HZ = 32, 24, 8, 10.0


def channels():
    return [
        qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um"),
        qogi.SpectralResponse([2000.0, 2200.0], [1.0, 1.0], name="4.5-5.0 um"),
    ]


def temperature_field(n_frames=T, height=H, width=W):
    """Blackbody temperatures [K] (T, H, W): a warm blob drifting up the frame."""
    t = np.arange(n_frames)[:, None, None]
    y = np.arange(height)[None, :, None]
    x = np.arange(width)[None, None, :]
    blob = np.exp(-((x - width / 2) ** 2 + (y - (height - 4 - t)) ** 2) / 20.0)
    return 285.0 + 0.5 * x / width + 25.0 * blob


def make_recording(n_channels=2, species=("CH4",), truth_kg_s=None, n_frames=T, nan=False):
    chs = channels()[:n_channels]
    temp = temperature_field(n_frames)
    frames = np.stack([ch.band_radiance(temp.ravel()).reshape(temp.shape) for ch in chs], axis=1)
    if nan:
        frames[3, 0, 5, 7] = np.nan
    cam = qogi.Camera("test camera", 1e-3, chs, frame_rate_hz=RATE_HZ, netd_K=0.02)
    scene = qogi.Scene(
        distance_m=3.0, ambient_temperature_K=288.0, pressure_Pa=101325.0, species=tuple(species)
    )
    truth = qogi.Truth({"CH4": truth_kg_s}) if truth_kg_s else None
    return qogi.Recording.from_arrays(
        frames,
        quantity="radiance",
        camera=cam,
        scene=scene,
        truth=truth,
        nonfinite="invalid" if nan else "error",
    )


@pytest.fixture
def rec_path(tmp_path):
    p = tmp_path / "small.h5"
    make_recording(truth_kg_s=1e-3).save(p)
    return p


@pytest.fixture
def store(tmp_path):
    from qogi_gui.store import UserStore

    return UserStore(tmp_path / "config")
