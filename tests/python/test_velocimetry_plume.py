"""Velocimetry on a synthetic plume with exact truth (a short version of the
plume study, scripts/velocimetry_plume_study.py, docs/velocimetry.md).

A simulated 5 SLPM CH4 release (qogi.synth.plume) gives exact column-density maps
and the mass-weighted velocity along every line of sight. The check is the
quantity the flux needs: on horizontal lines h above the exit, the
time-averaged mass-weighted upward velocity sum(c v) / sum(c), from each
method's velocity at the frame times (qogi.measure.velocimetry.frame_velocity) against
the truth. The bounds are coarse: they hold for every seed of the study with
a margin (the seeds' spread is in the comments) and catch a method that
regresses to texture tracking (which reads the steady plume base as nearly
at rest) or loses its flux level.
"""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi import synth
from qogi.measure import velocimetry as vel

PRESET = "lab-ch4-5slpm-gf320"
HEIGHTS_M = (0.02, 0.04, 0.08, 0.12)


def _case(rate_hz, frames, seed):
    sim = synth.simulate_preset(
        PRESET, duration_s=frames / rate_hz, frame_rate_hz=rate_hz, seed=seed
    )
    view, rel = sim.view, sim.release
    fp = view.distance_m * view.ifov_rad
    exit_row = 0.5 * (view.height_px - 1) - (rel.stack_height_m - view.center_z_m) / fp
    exit_col = 0.5 * (view.width_px - 1) + (rel.exit_x_m - view.center_x_m) / fp
    column = np.empty((sim.num_frames, view.height_px, view.width_px), np.float32)
    vz = np.empty_like(column)
    for t in range(sim.num_frames):
        m = sim.truth_maps(t)
        column[t] = m["column_kg_m2"]["CH4"]
        vz[t] = np.nan_to_num(m["velocity_z_m_s"])
    source = np.zeros(column.shape[1:], bool)
    half = 0.5 * rel.exit_diameter_m / fp + 1.0
    source[
        int(round(exit_row)) :, int(np.floor(exit_col - half)) : int(np.ceil(exit_col + half)) + 1
    ] = True
    rows = np.array([int(round(exit_row - h / fp)) for h in HEIGHTS_M])
    return column, vz, source, rows, fp


@pytest.fixture(scope="module")
def plume_100hz():
    return _case(100.0, 50, seed=3)


@pytest.fixture(scope="module")
def plume_15hz():
    return _case(15.0, 30, seed=3)


def _errors(case, rate_hz, method):
    """Error [%] of the time-averaged mass-weighted upward velocity per height."""
    column, vz, source, rows, fp = case
    masks = np.stack([vel.plume_mask(c) for c in column])
    seq = qogi.optical_flow_sequence(
        column, method=method, masks=masks, source_mask=source if method == "fluid" else None
    )
    _, v = vel.frame_velocity(seq)
    frames = np.arange(3, column.shape[0] - 1)
    c = column[frames][:, rows].astype(np.float64)
    est = (c * -v[frames][:, rows] * fp * rate_hz).sum(axis=(0, 2))
    true = (c * vz[frames][:, rows]).sum(axis=(0, 2))
    return 100.0 * (est / true - 1.0)


def test_fluid_keeps_the_flux_level_of_the_plume_at_100_hz(plume_100hz):
    err = _errors(plume_100hz, 100.0, "fluid")
    # These 50 frames with seeds 0-5: -32 to -12 % at 2-12 cm (the full study
    # in docs/velocimetry.md: 200 frames, 3 seeds). Texture tracking: < -80 %
    # at 2 cm; the fluid method before the study: -41 % at 2 cm.
    assert np.all(err > -40.0), err
    assert np.all(err < 10.0), err


def test_fluid_keeps_the_flux_level_of_the_plume_at_15_hz(plume_15hz):
    err = _errors(plume_15hz, 15.0, "fluid")
    # These 30 frames with seeds 0-5: -34 to -13 %.
    assert np.all(err > -45.0), err
    assert np.all(err < 15.0), err


def test_texture_tracking_misses_the_steady_plume_base(plume_100hz):
    """Brightness constancy reads the featureless base of the plume as nearly
    at rest (the thesis's near-stack failure); mass conservation does not."""
    fluid = _errors(plume_100hz, 100.0, "fluid")
    hs = _errors(plume_100hz, 100.0, "horn_schunck")
    # Seeds 0-5: Horn-Schunck -88 to -87 % at 2 cm, the fluid method -32 to -18 %.
    assert hs[0] < -60.0, hs
    assert fluid[0] > hs[0] + 30.0, (hs, fluid)


# -- the flux level from the transport of the line-integrated column ----------


def _fluctuating_column(v0_px, frames=150, height=120, width=40):
    """Exact 1-D transport through a decelerating steady velocity: gas enters
    across the bottom edge at a fluctuating rate q(t) and rises at
    v(y) = a + b y [px/frame] (v0 at the bottom, v0/2 at the top). With the
    travel time tau(y) from the bottom, the column of the line y is
    q(t - tau(y)) / v(y); each line's cell integral is exact, spread over x
    by a Gaussian. Returns the (T, H, W) column, v(y) and the exact forward
    displacement (pairs) of every row [px/frame, y down]."""
    a, b = 0.5 * v0_px, 0.5 * v0_px / height
    w1, w2 = 2 * np.pi / 23.0, 2 * np.pi / 9.0

    def Q(s):  # antiderivative of q(s) = 1 + 0.5 sin(w1 s) + 0.3 sin(w2 s + 1)
        return s - 0.5 / w1 * np.cos(w1 * s) - 0.3 / w2 * np.cos(w2 * s + 1.0)

    def tau(y):
        return np.log((a + b * height) / (a + b * y)) / b

    edges = np.arange(height + 1) - 0.5
    t = np.arange(frames)[:, None]
    lines = Q(t - tau(edges[1:])) - Q(t - tau(edges[:-1]))  # (T, H)
    x = np.arange(width)
    g = np.exp(-0.5 * ((x - 0.5 * width) / 6.0) ** 2)
    column = (lines[:, :, None] * (g / g.sum())[None, None, :]).astype(np.float32)
    y = np.arange(height, dtype=float)
    up = ((a + b * y) * np.exp(-b) - a) / b - y  # one frame later
    disp = np.broadcast_to(up[None, :, None], (frames - 1, height, width)).astype(np.float32)
    return column, a + b * y, disp


@pytest.mark.parametrize("v0", [1.5, 15.0])
def test_transport_flux_recovers_a_decelerating_fluctuating_plume(v0):
    column, v_true, _ = _fluctuating_column(v0)
    tf = vel.transport_flux(column, axis="up")
    # Lines whose gas of one frame ago is still in the frame (the bottom
    # ones are fed from across the edge).
    rows = np.arange(5, 120 - int(np.ceil(v0)) - 2)
    err = tf.velocity[rows] / v_true[rows] - 1.0
    assert np.all(np.abs(err) < 0.01), err
    # Turned to the right, the same plume gives the same profile.
    right = np.ascontiguousarray(column[:, ::-1, :].transpose(0, 2, 1))
    tr = vel.transport_flux(right, axis="right")
    np.testing.assert_allclose(tr.velocity[::-1][rows], tf.velocity[rows], rtol=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_transport_band_keeps_line_noise_out_of_a_faint_plumes_flux_level(seed):
    # A narrow plume (sigma 6 px) in frames 320 px wide with white noise, its
    # background taken per frame and line from 4-px strips at the frame's
    # edges (the pipeline's field background): the strips' noise is common
    # to a whole line and enters the line sums 320 times over. Over all the
    # frame's width the transport reads the velocity +9 ... +20 % off
    # (seeds 0-2); over the plume's band (transport_band) within 1.5 %.
    from qogi.pipeline.background import Background

    column, v_true, _ = _fluctuating_column(1.5, width=320)
    rng = np.random.default_rng(seed)
    noisy = (column + rng.normal(0, 4e-3, column.shape)).astype(np.float32)
    field = noisy - Background._edge_interpolation(noisy, True)
    rows = np.arange(5, 116)
    whole = vel.transport_flux(field, axis="up").velocity[rows] / v_true[rows] - 1.0
    band = vel.transport_band(field.mean(axis=0), "up")
    assert band[:, 160].all() and not band[:, :60].any() and not band[:, -60:].any()
    part = vel.transport_flux(field * band, axis="up").velocity[rows] / v_true[rows] - 1.0
    assert abs(np.median(whole)) > 0.08, np.median(whole)
    assert abs(np.median(part)) < 0.02, np.median(part)


def test_transport_band_is_the_same_over_a_background_offset_by_a_constant():
    # A temporal percentile background stands ~1.5 noise on the gas's side
    # of the true one (the noise's own percentile), so every gas-free pixel
    # of the field carries that constant. Thresholded on the raw time
    # average, the band took in the whole frame, and with it the line noise
    # it exists to keep out: the envelope's wall at -20 K in a 4 m/s wind
    # read -33 / -29 / -26 % (docs/validation.md). Above the field's median
    # the band is the plume's, whatever the constant.
    column, v_true, _ = _fluctuating_column(1.5, width=320)
    rng = np.random.default_rng(5)
    noise = 4e-3
    field = (column + rng.normal(0, noise, column.shape)).astype(np.float32)
    plain = vel.transport_band(field.mean(axis=0), "up")
    offset = vel.transport_band(field.mean(axis=0) + 1.5 * noise, "up")
    np.testing.assert_array_equal(offset, plain)
    assert plain[:, 160].all() and not plain[:, :60].any()
    rows = np.arange(5, 116)
    part = vel.transport_flux(field + 1.5 * noise, axis="up", mask=offset).velocity[rows]
    assert abs(np.median(part / v_true[rows] - 1.0)) < 0.03


def test_transport_band_keeps_the_whole_frame_without_a_plume():
    flat = np.random.default_rng(0).normal(0, 1.0, (60, 80))
    assert vel.transport_band(flat, "left").all()
    with pytest.raises(ValueError, match="axis"):
        vel.transport_band(flat, "north")
    with pytest.raises(ValueError, match="2-D"):
        vel.transport_band(flat[None], "up")


def test_transport_flux_with_dropped_frames_uses_each_pairs_interval():
    # 30 % of the frames dropped at random: with each pair's real interval the
    # velocity per frame interval is the full sequence's; taken as
    # consecutive, the frames read it ~1/0.7 too fast.
    column, v_true, _ = _fluctuating_column(1.5)
    keep = np.sort(np.random.default_rng(3).choice(150, 105, replace=False))
    rows = np.arange(5, 110)
    tf = vel.transport_flux(column[keep], axis="up", intervals=np.diff(keep).astype(float))
    err = tf.velocity[rows] / v_true[rows] - 1.0
    # The level to 1 % (seeds 0-3: median -0.03 ... +0.36 %); single lines
    # scatter by a few per cent with the irregular pairs (every 2nd frame
    # dropped: 0.1 %).
    assert abs(np.median(err)) < 0.01 and np.all(np.abs(err) < 0.06), err
    naive = vel.transport_flux(column[keep], axis="up")
    assert np.median(naive.velocity[rows] / v_true[rows]) > 1.2
    with pytest.raises(ValueError, match="intervals"):
        vel.transport_flux(column[keep], axis="up", intervals=np.ones(3))


def _evolving_column(shift, seed, frames=45, lines=136, change=0.6):
    """Gaussian structures released at the bottom line and carried up
    ``shift`` lines per frame, each one's amplitude changing by a factor
    exp(``change`` N(0, 1)) between frames (a plume's puffs, which mix as they
    go), over a line-wise noise of 2 %: (frames, lines, 3) float32."""
    rng = np.random.default_rng(seed)
    n = int((frames + lines / shift + 10) * 8)
    t0 = np.sort(rng.uniform(-lines / shift - 5, frames, n))
    log_amp = rng.normal(0.0, 0.5, n)
    width = rng.uniform(3.0, 8.0, n)
    y = np.arange(lines)[None, :]
    out = np.zeros((frames, lines, 3), np.float32)
    for t in range(frames):
        log_amp = log_amp + change * rng.normal(0.0, 1.0, n)
        c = (lines - 1) - shift * (t - t0)
        k = (c > -20) & (c < lines + 20)
        prof = (
            np.exp(log_amp[k])[:, None] * np.exp(-0.5 * ((y - c[k, None]) / width[k, None]) ** 2)
        ).sum(0)
        prof += 0.02 * prof.mean() * rng.normal(0.0, 1.0, lines)
        out[t] = np.maximum(prof, 0.0)[:, None] / 3
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_transport_flux_follows_structures_carried_across_a_third_of_the_frame(seed):
    """52 of 136 lines per frame (a 1 kg/h release in an 8 m/s wind at 15 Hz
    and 1.3 cm pixels), structures changing as they go: each level's own
    coarse search locks near the source on what changes slowly, and the fit
    from there read seed 2 at 44 lines per frame; the levels' common shift
    is tried too, and the start leaving less of the column unexplained kept."""
    col = _evolving_column(52.0, seed)
    tf = vel.transport_flux(col, axis="up", source_index=135)
    assert np.nanmedian(tf.displacement) == pytest.approx(52.0, rel=0.06)
    # The structures are carried: most of the column's change is explained.
    assert np.nanmedian(tf.unexplained) < 0.5


def test_transport_flux_explains_nothing_of_columns_that_are_new_every_frame():
    rng = np.random.default_rng(0)
    col = _evolving_column(10.0, 0)
    fresh = (col[0] * rng.uniform(0.5, 1.5, (45, 136, 1))).astype(np.float32)
    tf = vel.transport_flux(fresh, axis="up", source_index=135)
    assert np.nanmedian(tf.unexplained) > 0.8
    assert np.nanmedian(vel.transport_flux(col, axis="up", source_index=135).unexplained) < 0.2


def test_transport_flux_refuses_a_steady_plume():
    column, _, _ = _fluctuating_column(2.0)
    steady = np.repeat(column[:1], 10, axis=0)
    with pytest.raises(ValueError, match="steady"):
        vel.transport_flux(steady)
    with pytest.raises(ValueError, match="axis"):
        vel.transport_flux(column, axis="north")
    with pytest.raises(ValueError, match="source_index"):
        vel.transport_flux(column, source_index=500)


@pytest.mark.parametrize("v0", [1.5, 15.0])
def test_calibrate_flux_level_restores_a_flow_that_reads_30_percent_low(v0):
    column, v_true, disp = _fluctuating_column(v0)
    slow = vel.FlowSequence(
        np.zeros_like(disp),
        0.7 * disp,
        np.ones_like(disp),
        np.ones(disp.shape, bool),
        np.zeros(disp.shape[0]),
        "exact",
    )
    u, v, scale = vel.calibrate_flux_level(slow, column, axis="up")
    rows = np.arange(5, 120 - int(np.ceil(v0)) - 2)
    frames = slice(1, -1)
    c = column[frames].astype(np.float64)
    mass_weighted = (c * -v[frames]).sum(axis=(0, 2)) / c.sum(axis=(0, 2))
    err = mass_weighted[rows] / v_true[rows] - 1.0
    assert np.all(np.abs(err) < 0.02), err
    assert np.all(np.abs(u) == 0)
    np.testing.assert_allclose(scale[rows], 1 / 0.7, rtol=0.03)


def test_calibrate_flux_level_takes_the_transport_of_a_longer_stretch():
    # The flow covers the lower half of the plume (its 60 rows next to the
    # source), the transport flux is measured along all of it and given for
    # those rows: the flow's level follows it.
    column, v_true, disp = _fluctuating_column(1.5)
    full = vel.transport_flux(column, axis="up")
    part = vel.TransportFlux(
        *(
            np.asarray(a)[60:]
            for a in (full.flux, full.line_column, full.velocity, full.displacement)
        ),
        "up",
    )
    got = full.lines(slice(60, 120))
    for a, b in zip(
        (got.flux, got.line_column, got.velocity, got.displacement),
        (part.flux, part.line_column, part.velocity, part.displacement),
    ):
        np.testing.assert_array_equal(a, b)
    more = full.lines(slice(60, 120), scale=1.5)
    np.testing.assert_allclose(more.flux, 1.5 * got.flux)
    np.testing.assert_allclose(more.line_column, 1.5 * got.line_column)
    np.testing.assert_array_equal(more.velocity, got.velocity)
    lower = column[:, 60:]
    slow = vel.FlowSequence(
        np.zeros_like(disp[:, 60:]),
        0.7 * disp[:, 60:],
        np.ones_like(disp[:, 60:]),
        np.ones(disp[:, 60:].shape, bool),
        np.zeros(disp.shape[0]),
        "exact",
    )
    u, v, scale = vel.calibrate_flux_level(slow, lower, axis="up", transport=got)
    c = lower[1:-1].astype(np.float64)
    mass_weighted = (c * -v[1:-1]).sum(axis=(0, 2)) / c.sum(axis=(0, 2))
    rows = np.arange(5, 55)
    err = mass_weighted[rows] / v_true[60:][rows] - 1.0
    assert np.all(np.abs(err) < 0.02), err
    # A transport in other units moves the level with it; a wrong one is refused.
    _, v2, _ = vel.calibrate_flux_level(slow, lower, axis="up", transport=more)
    np.testing.assert_allclose(v2[1:-1][:, rows], 1.5 * v[1:-1][:, rows], rtol=1e-5)
    with pytest.raises(ValueError, match="transport must be along"):
        vel.calibrate_flux_level(slow, lower, axis="up", transport=full)


@pytest.fixture(scope="module")
def plume_100hz_1s():
    return _case(100.0, 100, seed=3)


@pytest.fixture(scope="module")
def plume_15hz_3s():
    return _case(15.0, 45, seed=3)


def _plume_frame_velocity_errors(case, rate_hz):
    column, vz, source, rows, fp = case
    exit_row = int(np.nonzero(source.any(axis=1))[0][0])
    masks = np.stack([vel.plume_mask(c) for c in column])
    u, v = vel.plume_frame_velocity(
        column, axis="up", source_index=exit_row, masks=masks, source_mask=source
    )
    frames = np.arange(3, column.shape[0] - 1)
    c = column[frames][:, rows].astype(np.float64)
    est = (c * -v[frames][:, rows] * fp * rate_hz).sum(axis=(0, 2))
    true = (c * vz[frames][:, rows]).sum(axis=(0, 2))
    return 100.0 * (est / true - 1.0)


def test_plume_frame_velocity_has_the_flux_level_at_100_hz(plume_100hz_1s):
    err = _plume_frame_velocity_errors(plume_100hz_1s, 100.0)
    # 100 frames with seeds 0-5: -10 to +8 % at 2-12 cm (the transport
    # estimate's statistics over 1 s); the fluid method alone: -20 to -30 %.
    assert np.all(np.abs(err) < 15.0), err


def test_plume_frame_velocity_has_the_flux_level_at_15_hz(plume_15hz_3s):
    err = _plume_frame_velocity_errors(plume_15hz_3s, 15.0)
    # 45 frames with seeds 0-5: -16 to +2 %.
    assert np.all(err > -25.0), err
    assert np.all(err < 15.0), err


@pytest.fixture(scope="module")
def wind_15hz():
    """The stack in a 6 m/s crosswind seen at 10 m and 15 Hz: the gas crosses
    ~28 px per frame (left to right), beyond what the 2-D flows can follow."""
    sim = synth.simulate_preset(
        "stack-20kgh-wind6-gf320", duration_s=3.0, frame_rate_hz=15.0, seed=1
    )
    view, rel = sim.view, sim.release
    fp = view.distance_m * view.ifov_rad
    exit_col = 0.5 * (view.width_px - 1) + (rel.exit_x_m - view.center_x_m) / fp
    maps = [sim.truth_maps(t) for t in range(sim.num_frames)]
    column = np.stack([m["column_kg_m2"]["CH4"] for m in maps]).astype(np.float32)
    flux_x = np.stack([m["flux_x_kg_m_s"]["CH4"] for m in maps]).astype(np.float64)
    return column, flux_x, exit_col, fp


def test_transport_flux_follows_a_plume_carried_by_wind(wind_15hz):
    # Gauss-Newton from a displacement of 1 px stopped in the first local
    # minimum (flux ~0.3 % of the truth); started from the correlation of the
    # line sums it finds the ~28 px/frame transport: measured +1, -5, -9 % at
    # 50, 100, 150 px downwind (seed 1).
    column, flux_x, exit_col, fp = wind_15hz
    tf = vel.transport_flux(column, axis="right", source_index=exit_col)
    cols = (np.array([50, 100, 150]) + exit_col).astype(int)
    true = flux_x[:, :, cols].sum(axis=1).mean(axis=0) * fp  # kg/s through the column
    est = tf.flux[cols] * fp * fp * 15.0  # kg/m2 px px/frame -> kg/s
    err = est / true - 1.0
    assert np.all(np.abs(err) < 0.15), err
    assert np.all((tf.displacement[cols] > 24) & (tf.displacement[cols] < 31)), tf.displacement[
        cols
    ]


def test_calibrate_flux_level_falls_back_to_the_transport_velocity(wind_15hz):
    # A flow running against the transport (what the 2-D flows return for
    # this plume near the stack) cannot be rescaled: the transport's own line
    # velocity replaces it, and the factor is reported as NaN.
    column, flux_x, exit_col, fp = wind_15hz
    backwards = np.full((column.shape[0] - 1,) + column.shape[1:], -5.0, np.float32)
    seq = vel.FlowSequence(
        backwards,
        np.zeros_like(backwards),
        np.ones_like(backwards),
        np.ones(backwards.shape, bool),
        np.zeros(backwards.shape[0]),
        "exact",
    )
    u, v, scale = vel.calibrate_flux_level(seq, column, axis="right", source_index=exit_col)
    tf = vel.transport_flux(column, axis="right", source_index=exit_col)
    assert np.all(np.isnan(scale))
    assert np.all(v == 0)
    cols = (np.array([50, 100, 150]) + exit_col).astype(int)
    np.testing.assert_allclose(u[0, 120, cols], tf.velocity[cols], rtol=1e-6)
    # A flow that follows the transport (30 % slow) is rescaled as before.
    slow = vel.FlowSequence(
        np.broadcast_to(0.7 * u[:1], backwards.shape).copy(),
        np.zeros_like(backwards),
        np.ones_like(backwards),
        np.ones(backwards.shape, bool),
        np.zeros(backwards.shape[0]),
        "exact",
    )
    _, _, scale = vel.calibrate_flux_level(slow, column, axis="right", source_index=exit_col)
    np.testing.assert_allclose(scale[cols], 1 / 0.7, rtol=0.05)
    with pytest.raises(ValueError, match="max_factor"):
        vel.calibrate_flux_level(slow, column, axis="right", source_index=exit_col, max_factor=1.0)
    # A flow that reads the wind backwards for the first third of the record
    # and 1.8x fast after (time average 0.93 of the transport, within the
    # factors; 18 % of its frame flux the wrong way, as the default flow did
    # on the outdoor sky release's seed 4): the transport's velocity replaces it.
    n = backwards.shape[0]
    lost = np.where(np.arange(n)[:, None, None] < n // 3, -0.8, 1.8) * u[:1]
    seq_lost = vel.FlowSequence(
        lost.astype(np.float32),
        np.zeros_like(backwards),
        np.ones_like(backwards),
        np.ones(backwards.shape, bool),
        np.zeros(n),
        "exact",
    )
    _, _, scale = vel.calibrate_flux_level(seq_lost, column, axis="right", source_index=exit_col)
    assert np.all(np.isnan(scale))
    _, _, scale = vel.calibrate_flux_level(
        seq_lost, column, axis="right", source_index=exit_col, max_reversed=0.5
    )
    assert np.isfinite(scale[cols]).all()
    with pytest.raises(ValueError, match="max_reversed"):
        vel.calibrate_flux_level(slow, column, axis="right", source_index=exit_col, max_reversed=0)


# -- pairs several frames apart at high frame rates ----------------------------


def test_typical_displacement_reads_the_structures_speed():
    # The decelerating 1-D plume moves 0.5 v0 ... v0 px per frame.
    for v0 in (2.0, 4.0):
        column, v_true, _ = _fluctuating_column(v0)
        d = vel.typical_displacement(column, axis="up")
        assert v_true.min() - 0.2 < d < v_true.max() + 0.2, (v0, d)
    fast, _, _ = _fluctuating_column(40.0)
    assert np.isnan(vel.typical_displacement(fast, axis="up", max_px=8))
    with pytest.raises(ValueError, match="max_px"):
        vel.typical_displacement(fast, max_px=1)


def test_interpolate_frame_velocity_is_linear_between_the_sampled_frames():
    t = np.arange(0, 10, 3, dtype=np.float32)  # frames 0, 3, 6, 9
    u = np.broadcast_to((3.0 * (1.0 + 0.5 * t))[:, None, None], (4, 2, 2)).astype(np.float32)
    v = -u
    fu, fv = vel.interpolate_frame_velocity(u, v, 3, 10)
    want = 1.0 + 0.5 * np.arange(10)  # px per frame at every frame
    np.testing.assert_allclose(fu[:, 0, 0], want, rtol=1e-6)
    np.testing.assert_allclose(fv[:, 1, 1], -want, rtol=1e-6)
    with pytest.raises(ValueError, match="ceil"):
        vel.interpolate_frame_velocity(u, v, 3, 13)


def test_pairs_three_frames_apart_keep_the_flux_level_at_100_hz(plume_100hz_1s):
    # The flow on every third frame, its frame velocities interpolated in
    # time, calibrated by the transport of every frame: the same flux as
    # consecutive pairs (the flow gives the pattern, the transport the level).
    column, vz, source, rows, fp = plume_100hz_1s
    exit_row = int(np.nonzero(source.any(axis=1))[0][0])
    norm = column / np.percentile(column, 99.5)
    tf = vel.transport_flux(norm, "up", exit_row)
    est = {}
    for stride in (1, 3):
        seq = vel.optical_flow_sequence(norm[::stride], source_mask=source, workers=0)
        fvel = None
        if stride > 1:
            fvel = vel.interpolate_frame_velocity(*vel.frame_velocity(seq), stride, len(norm))
        u, v, _ = vel.calibrate_flux_level(
            seq, norm, "up", exit_row, transport=tf, frame_velocities=fvel
        )
        frames = np.arange(3, column.shape[0] - 3)
        c = column[frames][:, rows].astype(np.float64)
        est[stride] = (c * -v[frames][:, rows] * fp * 100.0).sum(axis=(0, 2))
        true = (c * vz[frames][:, rows]).sum(axis=(0, 2))
        assert np.all(np.abs(est[stride] / true - 1) < 0.15), (stride, est[stride] / true)
    print("flux, pairs 3 frames apart / consecutive:", np.round(est[3] / est[1], 4))
    np.testing.assert_allclose(est[3], est[1], rtol=0.03)
