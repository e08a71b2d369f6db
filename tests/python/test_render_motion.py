"""The synthetic camera in motion: a vibrating tripod (the whole image moved
rigidly, drawn from a larger field so that no border is invented) and a filter
wheel (each channel seen at its own time within a turn)."""

from __future__ import annotations

import dataclasses

import h5py
import numpy as np
import pytest

import qogi
from qogi import _engine, synth
from qogi.synth import render

JIT = render.Jitter(rms_px=0.5, frequency_hz=2.0, rotation_rms_rad=1e-3, seed=2)


def _scene(width, height, frame_rate_hz=15.0, duration_s=0.6):
    release = synth.Release(
        rate=5.0,
        composition={"CH4": 1.0},
        exit_temperature_K=330.0,
        ambient_temperature_K=294.0,
        draft_m_s=0.02,
    )
    cam = qogi.camera_preset("gf320")
    cam = dataclasses.replace(cam, width=64, height=48, ifov_rad=4 * cam.ifov_rad)
    m = (width - 64) // 2
    view = synth.View.framing(
        release,
        (31.5 + m, 44.0 + m),
        width_px=width,
        height_px=height,
        ifov_rad=cam.ifov_rad,
        distance_m=1.5,
    )
    sim = synth.simulate(release, view, duration_s=duration_s, frame_rate_hz=frame_rate_hz, seed=3)
    return sim, cam


def test_jitter_has_the_asked_rms_and_frequency_and_is_seeded():
    t = np.arange(600) / 100.0
    m = JIT.motion(t)
    d = np.hypot(m[:, 0] - m[:, 0].mean(), m[:, 1] - m[:, 1].mean())
    assert np.sqrt(np.mean(d**2)) == pytest.approx(0.5, rel=1e-6)
    assert np.sqrt(np.mean(m[:, 2] ** 2)) == pytest.approx(1e-3, rel=1e-6)
    spec = np.abs(np.fft.rfft(m[:, 0])) ** 2
    f = np.fft.rfftfreq(len(t), 0.01)
    assert 0.9 < f[np.argmax(spec)] < 3.1  # within 2 Hz x [0.5, 1.5]
    np.testing.assert_array_equal(m, JIT.motion(t))
    assert not np.array_equal(m, dataclasses.replace(JIT, seed=3).motion(t))
    with pytest.raises(ValueError, match="rms_px"):
        render.Jitter(rms_px=-1)


def test_a_jittered_frame_is_the_still_frame_moved_with_no_invented_border(tmp_path):
    m = JIT.margin_px(64, 48)
    sim, cam = _scene(64 + 2 * m, 48 + 2 * m)
    bg = render.Background("plate", 285.0)
    shaken = render.render_recording(
        sim, cam, bg, tmp_path / "j.h5", noise=False, jitter=JIT, truth_maps=True
    )
    a = qogi.open_recording(shaken)
    assert a.shape == (9, 1, 48, 64)
    with h5py.File(shaken) as f:
        motion = np.stack(
            [
                f["truth/jitter_dx_px"][()],
                f["truth/jitter_dy_px"][()],
                f["truth/jitter_angle_rad"][()],
            ],
            axis=1,
        )
        assert f["truth/column_density_kg_m2_CH4"].shape == (9, 48, 64)
    np.testing.assert_allclose(motion, JIT.motion(sim.times_s))
    # The still camera: the same simulation drawn without motion, its centre cut out.
    still = render.SceneRenderer(
        sim, dataclasses.replace(cam, width=64 + 2 * m, height=48 + 2 * m), bg
    )
    for i in (2, 6):
        fa = a.frame(i)[0]
        fb = still.render_frame(i)[0, m:-m, m:-m]
        contrast = np.abs(fb - np.median(fb)).max()
        assert contrast > 0.01 * np.median(fb)  # the plume is in view
        # Put back in place by the recorded motion, the jittered frame is the
        # still one to the resampling's smoothing: bicubic there and back
        # takes ~10 % off the peak of a plume 2-3 px wide (this scene), far
        # less off its sum (the kernel's weights sum to one).
        back = _engine.warp_to_reference(fa, *motion[i])
        inner = (slice(4, -4), slice(4, -4))
        assert np.abs(back[inner] - fb[inner]).max() < 0.15 * contrast
        excess = (back - np.median(fb))[inner].sum(), (fb - np.median(fb))[inner].sum()
        assert excess[0] == pytest.approx(excess[1], rel=0.01)
        # It moved, and its edges hold the scene beyond the still frame's
        # edges (drawn, not a repeated border): the frame is the larger
        # field moved and cut, to the resampling's precision everywhere.
        assert np.abs(fa - fb).max() > 0.1 * contrast
        big = still.render_frame(i)
        c, s_ = np.cos(motion[i, 2]), np.sin(motion[i, 2])
        dx, dy = motion[i, :2]
        inv = (-(c * dx + s_ * dy), -(-s_ * dx + c * dy), -motion[i, 2])
        want = _engine.warp_to_reference(big, *inv)[0, m:-m, m:-m]
        np.testing.assert_allclose(fa, want, rtol=0, atol=1e-6 * np.median(fb))


@pytest.mark.slow
def test_a_filter_wheel_sees_each_channel_at_its_own_time(tmp_path):
    release = synth.Release(
        rate=5.0, composition={"CH4": 0.5, "CO2": 0.5}, exit_temperature_K=363.0, draft_m_s=0.02
    )
    cam = qogi.camera_preset("fast-m150")
    cam = dataclasses.replace(cam, width=64, height=48, ifov_rad=4 * cam.ifov_rad)
    view = synth.View.framing(
        release, (31.5, 44.0), width_px=64, height_px=48, ifov_rad=cam.ifov_rad, distance_m=1.5
    )
    # The wheel turns 100 times a second: the simulation runs at 4 x 100 Hz.
    sim = synth.simulate(release, view, duration_s=0.04, frame_rate_hz=400.0, seed=1)
    bg = render.Background("plate", 288.15)
    path = render.render_recording(sim, cam, bg, tmp_path / "w.h5", noise=False, filter_wheel=True)
    rec = qogi.open_recording(path)
    assert rec.shape == (4, 4, 48, 64)
    assert rec.camera.frame_rate_hz == pytest.approx(100.0)
    np.testing.assert_allclose(
        rec.attrs["channel_time_offset_s"], np.array([-1.5, -0.5, 0.5, 1.5]) / 400.0
    )
    np.testing.assert_allclose(rec.time_s, (4 * np.arange(4) + 1.5) / 400.0)
    # Channel k of frame i is the simultaneous rendering's channel k at
    # simulation frame 4 i + k (and not at the turn's other instants).
    r = render.SceneRenderer(sim, cam, bg)
    for k in range(4):
        got = rec.frame(2)[k]
        want = r.render_frame(4 * 2 + k)[k]
        other = r.render_frame(4 * 2 + (k + 2) % 4)[k]
        contrast = np.abs(want - np.median(want)).max()
        assert contrast > 0.01 * np.median(want)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * np.median(want))
        # (5 ms apart the gas has moved by under a pixel here: a few % of the contrast)
        assert np.abs(got - other).max() > 0.01 * contrast
