"""numpy and TIFF readers: metadata must come from the caller."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import qogi
import qogi.io as qio


def cam(n=1, rate=10.0):
    chs = [qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], f"ch{k}") for k in range(n)]
    return qogi.Camera("arraycam", 1e-3, chs, rate)


def scene():
    return qogi.Scene(5.0, 290.0, 1.0e5)


def test_npy_round_trip(tmp_path):
    f = np.random.default_rng(1).uniform(280, 300, (6, 2, 5, 7)).astype(np.float32)
    np.save(tmp_path / "f.npy", f)
    rec = qio.read_numpy(
        tmp_path / "f.npy", quantity="radiometric_temperature", camera=cam(2), scene=scene()
    )
    np.testing.assert_array_equal(rec.to_array(), f)
    np.testing.assert_allclose(rec.time_s, np.arange(6) / 10.0)


def test_npz_with_times_and_single_channel(tmp_path):
    f = np.random.default_rng(2).uniform(0.01, 0.02, (4, 5, 7))
    t = np.array([0.0, 0.05, 0.1, 0.15])
    np.savez(tmp_path / "f.npz", frames=f, time_s=t)
    rec = qio.read_recording(
        tmp_path / "f.npz", quantity="radiance", camera=cam(1, rate=20.0), scene=scene()
    )
    assert rec.shape == (4, 1, 5, 7)
    np.testing.assert_array_equal(rec.time_s, t)
    np.testing.assert_allclose(rec.frame(2)[0], f[2], rtol=1e-7)


def test_numpy_needs_the_metadata(tmp_path):
    np.save(tmp_path / "f.npy", np.ones((2, 3, 3), np.float32))
    with pytest.raises(
        qogi.RecordingError,
        match=r"f.npy: camera, scene: a numpy file holds only pixels.*Fix: pass",
    ):
        qio.read_numpy(tmp_path / "f.npy", quantity="radiance")
    np.savez(tmp_path / "g.npz", other=np.ones(3))
    with pytest.raises(qogi.RecordingError, match="no array 'frames'"):
        qio.read_numpy(tmp_path / "g.npz", quantity="radiance", camera=cam(), scene=scene())


def test_tiff_stack_float_and_counts(tmp_path):
    f = np.random.default_rng(3).uniform(280, 300, (5, 6, 8)).astype(np.float32)
    p = tmp_path / "s.tif"
    assert cv2.imwritemulti(str(p), list(f))
    rec = qio.read_tiff(p, quantity="radiometric_temperature", camera=cam(), scene=scene())
    np.testing.assert_array_equal(rec.to_array()[:, 0], f)
    counts = (f / 0.04).round().astype(np.uint16)
    q = tmp_path / "c.tiff"
    assert cv2.imwritemulti(str(q), list(counts))
    with pytest.raises(qogi.RecordingError, match=r"pages are integers \(uint16\).*scale="):
        qio.read_tiff(q, quantity="radiometric_temperature", camera=cam(), scene=scene())
    rec3 = qio.read_tiff(
        q, quantity="radiometric_temperature", camera=cam(), scene=scene(), scale=0.04
    )
    np.testing.assert_allclose(rec3.frame(1)[0], counts[1] * 0.04, rtol=1e-6)


def test_tiff_pages_grouped_into_channels(tmp_path):
    f = np.random.default_rng(4).uniform(280, 300, (3, 2, 4, 4)).astype(np.float32)
    p = tmp_path / "ch.tif"
    assert cv2.imwritemulti(str(p), list(f.reshape(6, 4, 4)))
    rec = qio.read_tiff(p, quantity="radiometric_temperature", camera=cam(2), scene=scene())
    np.testing.assert_array_equal(rec.to_array(), f)
    with pytest.raises(qogi.RecordingError, match="6 pages is not a multiple of the 4 channels"):
        qio.read_tiff(p, quantity="radiometric_temperature", camera=cam(4), scene=scene())


def test_read_recording_dispatch(tmp_path):
    with pytest.raises(ValueError, match=r"unknown recording file type '.xyz'"):
        qio.read_recording(tmp_path / "a.xyz")


def test_read_recording_recognises_a_file_by_its_first_bytes_not_its_name(tmp_path):
    """One registry of formats (qogi.io.open.FORMATS): a numpy file renamed
    .dat is still read as numpy, and file_kind names every format."""
    from qogi.io.open import FORMATS, file_kind

    frames = np.full((3, 1, 4, 5), 300.0, np.float32)
    p = tmp_path / "frames.npy"
    np.save(p, frames)
    renamed = tmp_path / "frames.dat"
    p.rename(renamed)
    assert file_kind(renamed) == "numpy"
    rec = qio.read_recording(
        renamed,
        quantity="radiometric_temperature",
        camera=cam(1),
        scene=scene(),
        time_s=np.arange(3) / 10.0,
    )
    assert rec.shape == (3, 1, 4, 5)
    assert {f.kind for f in FORMATS} == {"hdf5", "flir", "telops", "numpy", "tiff"}
