"""Velocimetry from Python: options, API, and recovery of exactly known motion.

The scenes are built here, independently of the C++ tests: a band-limited
random texture is an analytic sum of cosines, so the second frame is the
texture evaluated exactly at the back-traced positions (brightness
constancy), or the density divided by the map's Jacobian (continuity).
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import qogi
from qogi.measure import velocimetry as vel

H, W = 96, 128


def texture(seed=7, n=48, lam=(6.0, 24.0)):
    rng = np.random.default_rng(seed)
    lamb = rng.uniform(*lam, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    kx, ky = 2 * np.pi / lamb * np.cos(ang), 2 * np.pi / lamb * np.sin(ang)
    ph = rng.uniform(0, 2 * np.pi, n)
    amp = np.sqrt(2.0 / n)

    def t(x, y):
        x, y = np.asarray(x, float)[..., None], np.asarray(y, float)[..., None]
        return amp * np.cos(kx * x + ky * y + ph).sum(axis=-1)

    return t


def grid():
    y, x = np.mgrid[0:H, 0:W].astype(float)
    return x, y


def translated_pair(dx, dy, noise=0.01, seed=1):
    t = texture()
    x, y = grid()
    a = np.exp(0.4 * t(x, y))
    b = np.exp(0.4 * t(x - dx, y - dy))
    rng = np.random.default_rng(seed)
    s = noise * a.std()
    return a + rng.normal(0, s, a.shape), b + rng.normal(0, s, a.shape)


def epe(f, tu, tv, margin=16):
    sl = (slice(margin, -margin), slice(margin, -margin))
    err = np.hypot(f.u - tu, f.v - tv)[sl]
    ok = f.valid[sl]
    assert ok.mean() > 0.9
    return float(err[ok].mean())


# --- options -----------------------------------------------------------------

# The C++ field names, as documented in the engine headers; the variational
# methods (fluid, Horn-Schunck) share their pyramid's.
PYRAMID_FIELDS = (
    "levels",
    "min_level_size",
    "finest_level",
    "warm_levels",
    "warps",
    "iterations",
    "tolerance",
)
FIELDS = {
    "fluid": (
        "alpha",
        "alpha_div",
        "alpha_curl",
        "div_curl_scale",
        "smoothness_scale",
        "patch_search_scale",
        "patch_size",
        "patch_stride",
        "patch_iterations",
        "patch_search_warm",
        *PYRAMID_FIELDS,
    ),
    "horn_schunck": (
        "alpha",
        *PYRAMID_FIELDS,
    ),
    "lucas_kanade": (
        "window_sigma",
        "levels",
        "min_level_size",
        "finest_level",
        "iterations",
        "min_eigenvalue",
    ),
    "farneback": (
        "pyr_scale",
        "levels",
        "winsize",
        "iterations",
        "poly_n",
        "poly_sigma",
        "gaussian_window",
    ),
    "dis": (
        "finest_scale",
        "patch_size",
        "patch_stride",
        "gradient_descent_iterations",
        "variational_refinement_iterations",
        "variational_refinement_alpha",
        "variational_refinement_delta",
        "variational_refinement_gamma",
        "use_mean_normalization",
        "use_spatial_propagation",
    ),
    "piv": (
        "window_size",
        "initial_window_size",
        "overlap",
        "final_passes",
        "deform",
        "median_threshold",
        "median_epsilon",
        "min_correlation",
        "min_mask_fraction",
    ),
}


@pytest.mark.parametrize("method", list(vel.METHODS))
def test_options_have_the_engine_field_names_and_round_trip(method):
    cls = vel.METHODS[method]
    assert cls.fields == FIELDS[method]
    o = cls()
    assert tuple(o.to_dict()) == FIELDS[method]
    assert pickle.loads(pickle.dumps(o)) == o
    assert repr(o).startswith(cls.__name__ + "(")


def test_options_keywords_are_checked():
    o = vel.options_for("fluid", alpha=0.5, finest_level=0)
    assert (o.alpha, o.finest_level) == (0.5, 0)
    with pytest.raises(ValueError, match=r"FluidFlowOptions.alpha must be finite and > 0; got -1"):
        vel.FluidFlowOptions(alpha=-1)
    with pytest.raises(TypeError, match="has no field 'alfa'"):
        vel.FluidFlowOptions(alfa=1)
    with pytest.raises(ValueError, match=r"PivOptions.window_size must be even"):
        vel.PivOptions(window_size=15)
    o = vel.PivOptions()
    o.overlap = 0.99  # attributes are writable; check() and use validate them
    with pytest.raises(ValueError, match=r"PivOptions.overlap"):
        o.check()
    with pytest.raises(ValueError, match=r"PivOptions.overlap"):
        vel.FlowEstimator("piv", o)


# --- moving textures ---------------------------------------------------------


@pytest.mark.parametrize("method", list(vel.METHODS))
def test_every_method_recovers_a_translation(method):
    a, b = translated_pair(1.6, -0.9)
    f = qogi.optical_flow(a, b, method=method)
    assert f.method == method
    assert epe(f, 1.6, -0.9) < 0.1


def test_fluid_recovers_a_rotation_with_a_warm_start_sequence():
    # Rotation by 0.02 rad about the centre, over three frames.
    t = texture(seed=3)
    x, y = grid()
    cx, cy, th = W / 2, H / 2, 0.02
    frames = []
    for k in range(3):
        c, s = np.cos(-k * th), np.sin(-k * th)
        xs = cx + c * (x - cx) - s * (y - cy)
        ys = cy + s * (x - cx) + c * (y - cy)
        frames.append(np.exp(0.4 * t(xs, ys)))
    seq = qogi.optical_flow_sequence(np.array(frames))
    assert len(seq) == 2 and seq.u.shape == (2, H, W)
    tu = np.cos(th) * (x - cx) - np.sin(th) * (y - cy) - (x - cx)
    tv = np.sin(th) * (x - cx) + np.cos(th) * (y - cy) - (y - cy)
    for k in range(2):
        assert epe(seq[k], tu, tv) < 0.1


@pytest.mark.parametrize("workers", [1, 2])
def test_a_sequence_equals_its_pairs_each_warm_started_from_the_last(workers):
    # optical_flow_sequence writes each pair's flow into its arrays in place
    # (FlowEstimator._calc_into); the per-pair API, chunked the same way and
    # warm-started from the previous result, must give the same bits.
    t = texture(seed=4)
    x, y = grid()
    frames = np.array([np.exp(0.4 * t(x - 0.7 * k, y + 0.4 * k)) for k in range(6)], np.float32)
    mask = np.zeros((H, W), bool)
    mask[10:-10, 20:-20] = True
    seq = qogi.optical_flow_sequence(frames, masks=mask, workers=workers)
    bounds = np.linspace(0, 5, workers + 1).round().astype(int)
    for first, stop in zip(bounds[:-1], bounds[1:]):
        est, prev = vel.FlowEstimator(), None
        for k in range(max(0, first - vel.WARM_UP_PAIRS) if first else 0, stop):
            prev = est.calc(frames[k], frames[k + 1], mask, prev)
            if k >= first:
                for name in ("u", "v", "quality", "valid"):
                    np.testing.assert_array_equal(getattr(seq, name)[k], getattr(prev, name))
                assert seq.residual_ratio[k] == prev.residual_ratio
    assert seq.valid.dtype == bool and not seq.valid[:, ~mask].any()


def test_calc_into_checks_its_outputs_and_warm_start():
    a, b = translated_pair(1.0, 0.5)
    est = vel.FlowEstimator()
    out = (np.empty((H, W), np.float32),) * 3 + (np.empty((H, W), bool),)
    with pytest.raises(ValueError, match="warm=True needs a previous call"):
        est._calc_into(a, b, None, True, out)
    bad = (np.empty((H, W + 1), np.float32),) + out[1:]
    with pytest.raises(ValueError, match="output arrays must have the frames' shape"):
        est._calc_into(a, b, None, False, bad)
    with pytest.raises(TypeError):  # float64 output: never a silent copy
        est._calc_into(a, b, None, False, (np.empty((H, W)),) + out[1:])


def test_continuity_spreading_fluid_unbiased_brightness_constancy_biased():
    # A blob spreading radially, w = 0.02 (x - c): the exact next frame is
    # rho0(c + (x - c) / 1.02) / 1.02^2 (mass conserved by the map).
    t = texture(seed=5)
    x, y = grid()
    cx, cy, rate = W / 2, H / 2, 0.02

    def rho(xx, yy):
        env = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * 35.0**2))
        return env * np.exp(0.2 * t(xx, yy))

    a = rho(x, y)
    b = rho(cx + (x - cx) / (1 + rate), cy + (y - cy) / (1 + rate)) / (1 + rate) ** 2
    tu, tv = rate * (x - cx), rate * (y - cy)
    region = (x - cx) ** 2 + (y - cy) ** 2 <= 35.0**2
    errs = {}
    for m in ("fluid", "horn_schunck"):
        f = qogi.optical_flow(a, b, method=m)
        errs[m] = float(np.hypot(f.u - tu, f.v - tv)[region].mean())
    assert errs["fluid"] < 0.1
    assert errs["horn_schunck"] > 2 * errs["fluid"]


def test_mask_source_mask_and_estimator_reuse():
    a, b = translated_pair(1.0, 0.5)
    mask = np.zeros((H, W), bool)
    mask[20:70, 30:100] = True
    est = vel.FlowEstimator("fluid", vel.FluidFlowOptions(finest_level=0))
    f = est.calc(a, b, mask=mask)
    assert not f.valid[~mask].any() and f.valid[mask].mean() > 0.9
    src = np.zeros((H, W), bool)
    src[-3:, :] = True
    est.set_source_mask(src)
    f2 = est.calc(a, b, mask=mask, flow=f)
    assert f2.valid[mask].mean() > 0.9
    assert np.hypot(f2.u - 1.0, f2.v - 0.5)[f2.valid].mean() < 0.1
    with pytest.raises(ValueError, match="source_mask applies to the fluid method only"):
        vel.FlowEstimator("dis", source_mask=src)


def test_bad_input_raises_clear_errors():
    a = np.zeros((32, 32), np.float32)
    with pytest.raises(ValueError, match="method must be one of fluid, horn_schunck"):
        qogi.optical_flow(a, a, method="tvl1")
    with pytest.raises(TypeError, match="must be PivOptions; got DisOptions"):
        qogi.optical_flow(a, a, method="piv", options=vel.DisOptions())
    with pytest.raises(ValueError, match="same shape"):
        qogi.optical_flow(a, np.zeros((32, 33)))
    with pytest.raises(ValueError, match="2-D frame"):
        qogi.optical_flow(np.zeros((2, 32, 32)), a)
    with pytest.raises(ValueError, match="at least 16 x 16 px"):
        qogi.optical_flow(np.zeros((8, 8)), np.zeros((8, 8)))
    nan = a.copy()
    nan[3, 3] = np.nan
    with pytest.raises(ValueError, match="prev contains NaN"):
        qogi.optical_flow(nan, a)
    with pytest.raises(ValueError, match="mask must have the frames' shape"):
        qogi.optical_flow(a, a, mask=np.ones((4, 4), bool))
    with pytest.raises(ValueError, match=r"\(T, H, W\) stack with T >= 2"):
        qogi.optical_flow_sequence(a[None])


def test_progress_callback_can_cancel_a_sequence():
    a, b = translated_pair(1.0, 0.0)
    seen = []

    def progress(fraction):
        seen.append(fraction)
        return False

    with pytest.raises(qogi.Cancelled):
        qogi.optical_flow_sequence(np.array([a, b, a]), method="farneback", progress=progress)
    assert seen == [0.5]


# --- units -------------------------------------------------------------------


def test_units_follow_the_camera_geometry():
    # 2 px/frame seen from 3 m with 1 mrad pixels at 15 Hz: 2 x 3 mm x 15 /s.
    assert vel.to_metres_per_second(2.0, 3.0, 1e-3, 15.0) == pytest.approx(0.09)
    f = vel.Flow(
        np.full((2, 2), 2.0, np.float32),
        np.zeros((2, 2), np.float32),
        np.ones((2, 2), np.float32),
        np.ones((2, 2), bool),
        0.0,
        "fluid",
    )
    u, _ = f.in_metres_per_second(3.0, 1e-3, 15.0)
    np.testing.assert_allclose(u, 0.09, rtol=1e-6)
    with pytest.raises(ValueError, match="frame_rate_hz must be finite and > 0"):
        vel.to_metres_per_second(1.0, 3.0, 1e-3, 0.0)


# --- post-processing ----------------------------------------------------------


def smooth_field():
    y, x = np.mgrid[0:30, 0:40].astype(np.float32)
    return 0.03 * x, 1.0 - 0.02 * y


def test_median_test_and_validate_fix_planted_outliers():
    u, v = smooth_field()
    planted = [(5, 5), (20, 13), (12, 33)]
    u2 = u.copy()
    for p in planted:
        u2[p] += 2.0
    out = vel.normalised_median_test(u2, v)
    assert set(zip(*np.nonzero(out))) == set(planted)
    f = vel.Flow(u2, v.copy(), np.ones_like(u), np.ones(u.shape, bool), 0.0, "piv")
    g, outliers = vel.validate(f)
    assert (outliers == out).all()
    np.testing.assert_allclose(g.u, u, atol=1e-5)  # full rings: exact for a linear field
    assert not g.valid[outliers].any() and g.valid[~outliers].all()
    assert (f.u == u2).all()  # input untouched


def test_replace_vectors_limits_its_reach():
    u = np.zeros((1, 8), np.float32)
    u[0, 0] = 3.0
    keep = np.zeros((1, 8), bool)
    keep[0, 0] = True
    ru, _, filled = vel.replace_vectors(u, u * 0, keep, max_distance=2)
    assert filled.tolist() == [[False, True, True] + [False] * 5]
    assert ru[0, 2] == 3.0 and ru[0, 3] == 0.0


def test_temporal_filter_removes_a_spike_in_a_sequence():
    T = 5
    u = np.ones((T, 6, 7), np.float32)
    u[2, 3, 3] = 40.0
    seq = vel.FlowSequence(
        u, np.zeros_like(u), np.ones_like(u), np.ones(u.shape, bool), np.zeros(T), "fluid"
    )
    filt = vel.temporal_filter(seq, window=3)
    assert filt.u[2, 3, 3] == 1.0 and filt.valid.all()
    fu, _, _ = vel.temporal_filter(u, np.zeros_like(u), window=3, statistic="mean")
    assert fu[2, 3, 3] == pytest.approx(14.0)
    with pytest.raises(ValueError, match="window must be odd"):
        vel.temporal_filter(seq, window=4)
    with pytest.raises(ValueError, match="statistic must be 'median' or 'mean'"):
        vel.temporal_filter(seq, statistic="mode")


def test_frame_velocity_is_exact_for_accelerating_gas_where_pairs_lag():
    """Trajectories x(t) = x0 + a t + g t^2 / 2 (every pixel): pair k moves the
    gas by a + g (k + 1/2); the velocity at frame t is a + g t."""
    T, a, g = 6, 2.0, 0.6
    v = np.stack([np.full((40, 48), -(a + g * (k + 0.5)), np.float32) for k in range(T - 1)])
    seq = vel.FlowSequence(
        np.zeros_like(v), v, np.ones_like(v), np.ones(v.shape, bool), np.zeros(T - 1), "fluid"
    )
    fu, fv = vel.frame_velocity(seq)
    assert fv.shape == (T, 40, 48)
    assert fv[1:-1, 20, 24] == pytest.approx([-(a + g * t) for t in range(1, T - 1)], abs=1e-4)
    assert np.abs(fu).max() < 1e-6
    with pytest.raises(ValueError, match=r"same shape|one shape"):
        vel.frame_velocity(v, v[:, :10])


@pytest.mark.parametrize("workers", [1, 2])
def test_a_sequence_into_given_arrays_without_quality_has_the_same_displacements(workers):
    # The pipeline's memory-lean form: the displacements written into the
    # first T - 1 frames of (T, H, W) buffers, quality and validity not kept.
    t = texture(seed=4)
    x, y = grid()
    frames = np.array([np.exp(0.4 * t(x - 0.7 * k, y + 0.4 * k)) for k in range(6)], np.float32)
    full = qogi.optical_flow_sequence(frames, workers=workers)
    buf = np.full((2, 6, H, W), np.nan, np.float32)
    lean = qogi.optical_flow_sequence(
        frames, workers=workers, out=(buf[0, :-1], buf[1, :-1]), keep_quality=False
    )
    assert lean.u.base is buf or np.shares_memory(lean.u, buf)
    np.testing.assert_array_equal(buf[0, :-1], full.u)
    np.testing.assert_array_equal(buf[1, :-1], full.v)
    np.testing.assert_array_equal(lean.residual_ratio, full.residual_ratio)
    assert lean.quality is None and lean.valid is None
    assert np.isnan(buf[:, -1]).all()  # the frame of room is left alone
    with pytest.raises(ValueError, match="keep_quality=False"):
        lean[0]
    with pytest.raises(ValueError, match=r"out's u must be a C-contiguous float32 array"):
        qogi.optical_flow_sequence(frames, out=(buf[0], buf[1]))


@pytest.mark.parametrize("frames", [2, 3, 17, vel.FRAME_VELOCITY_CHUNK * 2 + 3])
def test_frame_velocity_in_place_equals_frame_velocity(frames):
    rng = np.random.default_rng(frames)
    u = (3 * rng.normal(size=(frames - 1, 24, 30))).astype(np.float32)
    v = (3 * rng.normal(size=(frames - 1, 24, 30))).astype(np.float32)
    ref_u, ref_v = vel.frame_velocity(u, v)
    bu = np.empty((frames, 24, 30), np.float32)
    bv = np.empty_like(bu)
    bu[:-1], bv[:-1] = u, v
    got_u, got_v = vel.frame_velocity_in_place(bu, bv)
    assert got_u is bu and got_v is bv
    np.testing.assert_array_equal(bu, ref_u)
    np.testing.assert_array_equal(bv, ref_v)
    with pytest.raises(ValueError, match="writeable C-contiguous float32"):
        vel.frame_velocity_in_place(bu.astype(float), bv)


def test_invert_displacement_undoes_a_rotation():
    x, y = grid()
    th, cx, cy = 0.04, 63.5, 47.5
    u = cx + np.cos(th) * (x - cx) - np.sin(th) * (y - cy) - x
    v = cy + np.sin(th) * (x - cx) + np.cos(th) * (y - cy) - y
    bu, bv = vel.invert_displacement(u, v)
    ex = cx + np.cos(th) * (x - cx) + np.sin(th) * (y - cy) - x
    ey = cy - np.sin(th) * (x - cx) + np.cos(th) * (y - cy) - y
    sl = (slice(8, -8), slice(8, -8))
    assert np.abs(bu - ex)[sl].max() < 2e-3 and np.abs(bv - ey)[sl].max() < 2e-3
    with pytest.raises(ValueError, match="iterations must be >= 1"):
        vel.invert_displacement(u, v, iterations=0)


def test_plume_mask_and_restrict_to_mask():
    x, y = grid()
    blob = np.exp(-((x - 64) ** 2 + (y - 48) ** 2) / (2 * 10.0**2))
    m = vel.plume_mask(blob, threshold=0.5, dilate_radius=0)
    # exp(-r^2 / 200) >= 0.5 within r = 10 sqrt(2 ln 2) = 11.77 px
    assert m.sum() == pytest.approx(np.pi * 11.77**2, rel=0.05)
    f = qogi.optical_flow(*translated_pair(1.0, 0.0), method="farneback")
    g = vel.restrict_to_mask(f, m)
    assert not g.valid[~m].any() and f.valid[~m].any()


def test_thread_count_can_be_set():
    n = vel.get_num_threads()
    vel.set_num_threads(1)
    assert vel.get_num_threads() == 1
    vel.set_num_threads(0)
    assert vel.get_num_threads() >= 1
    vel.set_num_threads(n)
    with pytest.raises(ValueError, match="num_threads must be >= 0"):
        vel.set_num_threads(-2)
