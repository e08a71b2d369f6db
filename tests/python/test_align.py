"""The alignment stage: a vibrating camera's frames put back in place, and a
filter wheel's channels brought to the turn's time, before the background and
the inversion see them."""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi.io.recording import Recording, Scene
from qogi.pipeline import QuantifyConfig, align, setup
from qogi.pipeline.surfaces import Surface
from qogi.synth.render import Jitter

W, H = 96, 80
RATE_HZ = 30.0


def _texture(seed: int):
    """A band-limited scene texture [K] (plane waves, periods 5-30 px),
    evaluated exactly at any point."""
    rng = np.random.default_rng(seed)
    period = rng.uniform(5, 30, 40)
    direction = rng.uniform(0, 2 * np.pi, 40)
    k = 2 * np.pi / period
    kx, ky = k * np.cos(direction), k * np.sin(direction)
    phase = rng.uniform(0, 2 * np.pi, 40)
    amp = rng.uniform(0.02, 0.06, 40)

    def tex(x, y):
        return (amp * np.cos(kx * x[..., None] + ky * y[..., None] + phase)).sum(axis=-1)

    return tex


def _shaken_scene(motion: np.ndarray, seed: int = 1, netd_K: float = 0.02) -> Recording:
    """Radiometric temperature frames [K] of a textured wall at 290 K with
    warm puffs rising through it, seen by a camera moving by ``motion``
    (T, 3): the frame's content at W(x) is the still scene's at x."""
    tex = _texture(seed)
    rng = np.random.default_rng(seed + 100)
    y, x = np.mgrid[0:H, 0:W].astype(float)
    cx, cy = 0.5 * (W - 1), 0.5 * (H - 1)
    frames = []
    for i, (dx, dy, a) in enumerate(motion):
        # The still scene's point seen at pixel (x, y): W^-1(x, y).
        c, s = np.cos(a), np.sin(a)
        ux, uy = x - cx - dx, y - cy - dy
        xs, ys = cx + c * ux + s * uy, cy - s * ux + c * uy
        img = 290.0 + tex(xs, ys)
        for p in range(4):  # puffs rising at 1.5 px per frame
            py = H - 10 - ((1.5 * i + 20 * p) % (H - 10))
            img += 1.5 * np.exp(-((xs - 48) ** 2 + (ys - py) ** 2) / (2 * 4.0**2))
        frames.append(img + rng.normal(0, netd_K, img.shape))
    cam = qogi.camera_preset("gf320")
    cam = qogi.Camera(cam.name, cam.ifov_rad, cam.channels, RATE_HZ, netd_K)
    scene = Scene(distance_m=3.0, ambient_temperature_K=290.0, pressure_Pa=101325.0)
    return Recording.from_arrays(
        np.asarray(frames, np.float32)[:, None],
        quantity="radiometric_temperature",
        camera=cam,
        scene=scene,
    )


def _run(rec: Recording):
    cfg = QuantifyConfig(species=["CH4"], source=(48.0, 75.0), background="percentile")
    surfaces = [Surface([(30, 40), (66, 40)], "S1")]
    run = setup.prepare(rec, surfaces, cfg, None, False)
    align.prepare(run)
    return run


def test_half_a_pixel_of_jitter_is_measured_and_undone_to_within_the_noise():
    n = 60
    motion = Jitter(rms_px=0.5, frequency_hz=2.0, rotation_rms_rad=5e-4, seed=3).motion(
        np.arange(n) / RATE_HZ
    )
    rec = _shaken_scene(motion)
    run = _run(rec)
    info = run.info["stabilisation"]
    assert info["status"].startswith("on"), info
    # Measured on the sampled frames: the applied 0.5 px rms (plus the rotation at the corner).
    corner = np.hypot(0.5 * (W - 1), 0.5 * (H - 1))
    d = motion - np.median(motion, axis=0)
    applied = np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2 + (d[:, 2] * corner) ** 2))
    assert info["jitter_rms_px"] == pytest.approx(applied, rel=0.1)
    assert info["residual_rms_px"] < 0.03
    assert not run.warnings.has("jitter-residual")
    # Every frame's shift against the truth, up to the reference's own place
    # (the median of the sampled frames): the precision the texture and the
    # 0.02 K noise allow (info["precision_px"], ~0.005 px) plus the puffs.
    src = run.rec._source
    est = np.array([src.shift_of_frame(i) for i in range(n)])
    err = est - motion
    err -= np.median(err, axis=0)
    assert np.sqrt(np.mean(err[:, 0] ** 2)) < 0.02
    assert np.sqrt(np.mean(err[:, 1] ** 2)) < 0.02
    assert np.sqrt(np.mean(err[:, 2] ** 2)) * corner < 0.03
    # The stabilised frames hold still: the texture's change about its
    # temporal median, away from the puffs, back to the 0.02 K noise.
    still = run.rec.frames(0, n, quantity="radiometric_temperature")[:, 0, 6:-6, 6:30]
    shaken = rec.frames(0, n)[:, 0, 6:-6, 6:30]
    assert np.std(still - np.median(still, axis=0)) < 0.023
    assert np.std(shaken - np.median(shaken, axis=0)) > 0.035


def test_a_still_camera_is_left_alone():
    n = 40
    rec = _shaken_scene(np.zeros((n, 3)))
    run = _run(rec)
    info = run.info["stabilisation"]
    assert info["status"].startswith("off: measured jitter"), info
    assert info["jitter_rms_px"] < align.JITTER_NEGLIGIBLE_PX
    assert run.rec is rec


def test_a_uniform_scene_has_nothing_to_register_on():
    n = 20
    cam = qogi.camera_preset("gf320")
    cam = qogi.Camera(cam.name, cam.ifov_rad, cam.channels, RATE_HZ, 0.02)
    frames = 290.0 + np.random.default_rng(0).normal(0, 0.02, (n, 1, H, W))
    rec = Recording.from_arrays(
        frames,
        quantity="radiometric_temperature",
        camera=cam,
        scene=Scene(distance_m=3.0, ambient_temperature_K=290.0, pressure_Pa=101325.0),
    )
    run = _run(rec)
    assert run.info["stabilisation"]["status"].startswith("off: the scene has no texture")
    assert run.rec is rec


def test_a_shake_beyond_what_is_corrected_is_a_warning():
    n = 40
    motion = np.zeros((n, 3))
    motion[30:, 0] = 6.0  # the camera bumped 6 px to the right for the last quarter
    run = _run(_shaken_scene(motion))
    assert run.warnings.has("jitter-uncorrected")


def test_a_blob_rising_over_a_faint_gradient_is_not_taken_for_a_camera_motion():
    """A still camera, 8 frames of a warm blob rising 1 px per frame over a
    0.5 K gradient (32 x 24 px, no noise: the viewer tests' recording): the
    registration follows the blob (16 px rms "jitter", 20 px left after
    putting it back). Resampling by that would move the gas: no frame may be
    moved, and the warning says why."""
    t = np.arange(8)[:, None, None]
    y = np.arange(24)[None, :, None]
    x = np.arange(32)[None, None, :]
    temp = 285.0 + 0.5 * x / 32 + 25.0 * np.exp(-((x - 16) ** 2 + (y - (20 - t)) ** 2) / 20.0)
    chs = [
        qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um"),
        qogi.SpectralResponse([2000.0, 2200.0], [1.0, 1.0], name="4.5-5.0 um"),
    ]
    frames = np.stack([ch.band_radiance(temp.ravel()).reshape(temp.shape) for ch in chs], axis=1)
    rec = Recording.from_arrays(
        frames,
        quantity="radiance",
        camera=qogi.Camera("test camera", 1e-3, chs, frame_rate_hz=10.0, netd_K=0.02),
        scene=Scene(distance_m=3.0, ambient_temperature_K=288.0, pressure_Pa=101325.0),
    )
    run = _run(rec)
    assert run.info["stabilisation"]["status"].startswith("off"), run.info["stabilisation"]
    assert run.rec is rec
    assert run.warnings.has("jitter-uncorrected")


def _wheel_scene(offsets_s=None, n=12, speed_px=3.0):
    """Four channels of a warm blob rising at ``speed_px`` per turn in front
    of a textured wall; channel k seen ``offsets_s[k]`` after the turn's time."""
    cam = qogi.camera_preset("fast-m150")
    rate = cam.frame_rate_hz
    tex = _texture(4)
    y, x = np.mgrid[0:H, 0:W].astype(float)
    wall = 290.0 + tex(x, y)
    frames = np.empty((n, 4, H, W))
    rng = np.random.default_rng(2)
    offs = np.zeros(4) if offsets_s is None else np.asarray(offsets_s)
    for i in range(n):
        for k in range(4):
            cy = H - 15 - speed_px * (i + offs[k] * rate)
            blob = np.exp(-((x - 48) ** 2 + (y - cy) ** 2) / (2 * 5.0**2))
            frames[i, k] = wall + (2.0 + k) * blob + rng.normal(0, cam.netd_K, (H, W))
    scene = Scene(distance_m=3.0, ambient_temperature_K=290.0, pressure_Pa=101325.0)
    rec = Recording.from_arrays(
        frames.astype(np.float32),
        quantity="radiometric_temperature",
        camera=qogi.Camera(cam.name, cam.ifov_rad, cam.channels, rate, cam.netd_K),
        scene=scene,
    )
    if offsets_s is not None:
        rec.attrs["channel_time_offset_s"] = np.asarray(offsets_s, float)
    return rec


def test_a_filter_wheels_channels_are_brought_to_the_turns_time():
    offsets = np.array([-3.75, -1.25, 1.25, 3.75]) * 1e-3  # the fast-m150 at 100 turns/s
    wheel = _wheel_scene(offsets)
    simultaneous = _wheel_scene(None)
    cfg = QuantifyConfig(species=["CH4"], source=(48.0, 75.0), background="percentile")
    run = setup.prepare(wheel, [Surface([(30, 40), (66, 40)], "S1")], cfg, None, False)
    align.prepare(run)
    assert run.info["channel_timing"]["status"].startswith("on"), run.info["channel_timing"]
    i = 6
    fixed = run.rec.frame(i, quantity="radiometric_temperature")
    raw = wheel.frame(i, quantity="radiometric_temperature")
    want = simultaneous.frame(i, quantity="radiometric_temperature")
    for k in range(4):
        # The blob's misregistration (0.4-1.1 px) against the simultaneous
        # channels: rms over the frame at least halved (the optical flow on a
        # featureless blob is ~20 % off and blurs its edges).
        before = np.sqrt(np.mean((raw[k] - want[k]) ** 2))
        after = np.sqrt(np.mean((fixed[k] - want[k]) ** 2))
        assert before > 0.015  # K
        assert after < 0.5 * before


@pytest.mark.slow
def test_the_filter_wheels_real_timing_on_a_moving_heated_plume_is_undone(tmp_path):
    """The heated lab release through the four-filter fast-m150 at 100
    turns/s, each filter 2.5 ms after the previous one (seed 5, 20 turns,
    the temperature inferred): read with the channels' times ignored it was
    -28 / -27 / -24 % against the same plume seen with simultaneous
    channels (docs/camera.md); the alignment brings them to the turn's
    time, within 10 % (+0.2 / +0.4 / +0.7 % measured)."""
    import importlib.util
    from pathlib import Path

    script = Path(__file__).resolve().parents[2] / "scripts" / "channel_offset_effect.py"
    spec = importlib.util.spec_from_file_location("channel_offset_effect", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out, _infos, offsets, turns = mod.wheel_rates(0.2, 5, str(tmp_path))
    assert turns == 20
    np.testing.assert_allclose(offsets, [-3.75e-3, -1.25e-3, 1.25e-3, 3.75e-3], atol=1e-6)
    ref = out["simultaneous"]
    blind = out["wheel, uncorrected"] / ref - 1
    fixed = out["wheel"] / ref - 1
    assert (blind < -0.15).all(), blind  # the effect the timing has
    assert (np.abs(fixed) < 0.10).all(), fixed
