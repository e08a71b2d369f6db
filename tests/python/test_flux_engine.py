"""The flux module of the engine (engine/flux) against the numpy code it
replaced: the transport flux, its typical displacement and the flux level
(qogi.measure.velocimetry) and the pipeline's surface flux, on seeded synthetic
inputs (tests/python/flux_cases.py), against outputs frozen from the numpy
implementation before the port (tests/data/flux_reference.npz); and
qogi.measure.flux.surface_rate against an analytic plume and the pipeline's
``_surface_flux`` on the same inputs."""

from __future__ import annotations

from pathlib import Path

import flux_cases as fc
import numpy as np
import pytest

from qogi import _engine
from qogi.measure import flux
from qogi.measure import velocimetry as vel
from qogi.pipeline.flux import _surface_flux

REFERENCE = Path(__file__).resolve().parents[1] / "data" / "flux_reference.npz"
# The engine's time-of-flight misfit interpolates the cumulative line column
# by cubic Hermite (a continuous derivative in the displacements; the numpy
# code interpolated it linearly, whose derivative jumps at whole pixels): on
# these cases that moves the transport's flux, velocity and displacement by
# < 0.13 % (1e-7 before the change), and the flux level's factors with them.
TRANSPORT_RTOL = 2e-3


@pytest.fixture(scope="module")
def ref():
    with np.load(REFERENCE) as z:
        return dict(z)


def _close(got, want, what, rtol=1e-9, atol=1e-12):
    got, want = np.asarray(got, float), np.asarray(want, float)
    assert got.shape == want.shape, what
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want), err_msg=what)
    ok = ~np.isnan(want)
    np.testing.assert_allclose(got[ok], want[ok], rtol=rtol, atol=atol, err_msg=what)


def _close_digest(got, want, what):
    """A velocity digest (sums over frames, rows, columns, which mix lines of
    different factors) within TRANSPORT_RTOL of its largest entry."""
    _close(
        fc.digest(got), want, what, rtol=TRANSPORT_RTOL, atol=TRANSPORT_RTOL * np.abs(want).max()
    )


@pytest.mark.parametrize("case", fc.TRANSPORT_CASES, ids=[c[0] for c in fc.TRANSPORT_CASES])
def test_transport_flux_and_flux_level_agree_with_the_numpy_implementation(ref, case):
    name, seed, axis, src, kind = case
    frames = fc.turned(fc.puffing_plume(seed), axis)
    tf = vel.transport_flux(frames, axis, src, intervals=fc.intervals(kind, frames.shape[0], seed))
    for f in ("flux", "line_column", "velocity", "displacement"):
        # Gauss-Newton to 1e-4 px from the same start, on the Hermite misfit.
        rtol = 1e-9 if f == "line_column" else TRANSPORT_RTOL
        _close(getattr(tf, f), ref[f"tf_{name}_{f}"], f"{name} {f}", rtol=rtol)
    assert vel.typical_displacement(frames, axis) == pytest.approx(
        float(ref[f"td_{name}"]), rel=1e-10
    )
    for level_name, level in (("slow", 1.6), ("backwards", -3.0)):
        fu, fv = fc.frame_velocities(seed, frames.shape, axis, level)
        u, v, scale = vel.calibrate_flux_level(None, frames, axis, src, frame_velocities=(fu, fv))
        _close(
            scale,
            ref[f"cal_{name}_{level_name}_scale"],
            f"{name} {level_name} scale",
            rtol=TRANSPORT_RTOL,
        )
        _close_digest(u, ref[f"cal_{name}_{level_name}_u"], f"{name} {level_name} u")
        _close_digest(v, ref[f"cal_{name}_{level_name}_v"], f"{name} {level_name} v")
        assert u.dtype == np.float32 and v.dtype == np.float32 and scale.dtype == np.float32


def test_flux_level_from_a_sequence_and_a_given_transport_agrees_with_numpy(ref):
    frames, fu, fv, seq = fc.flow_sequence_case()
    u, v, scale = vel.calibrate_flux_level(seq, frames, "up", None, smooth_px=0.0)
    _close(scale, ref["cal_seq_scale"], "seq scale", rtol=TRANSPORT_RTOL)
    _close_digest(u, ref["cal_seq_u"], "seq u")
    _close_digest(v, ref["cal_seq_v"], "seq v")
    u, v, scale = fc.calibrate_given_transport(frames, fu, fv)
    _close(scale, ref["cal_part_scale"], "part scale", rtol=TRANSPORT_RTOL)
    _close_digest(u, ref["cal_part_u"], "part u")
    _close_digest(v, ref["cal_part_v"], "part v")


def test_a_flow_against_the_transport_is_replaced_in_the_given_stacks_to_the_bit():
    # The transport's velocity is written over the caller's frame velocities
    # (no second pair of stacks), the same values as the (T, H, W) result.
    frames = fc.puffing_plume(2)
    fu, fv = fc.frame_velocities(2, frames.shape, "up", -3.0)
    u, v, scale = vel.calibrate_flux_level(None, frames, "up", frame_velocities=(fu, fv))
    assert np.isnan(scale).all() and u is fu and v is fv
    tu, tv = vel._transport_velocity(vel.transport_flux(frames, "up"), frames.shape)
    np.testing.assert_array_equal(u, tu)
    np.testing.assert_array_equal(v, tv)


@pytest.mark.parametrize("axis", ["up", "left"])
def test_transport_flux_with_a_mask_is_that_of_the_masked_frames_to_the_bit(axis):
    # The pipeline gives the plume's band as a mask instead of a second stack.
    rng = np.random.default_rng(3)
    frames = rng.normal(size=(12, 30, 26)).astype(np.float32)
    frames += np.linspace(0.0, 4.0, 12)[:, None, None].astype(np.float32)  # a changing plume
    mask = rng.random((30, 26)) > 0.3
    plain = vel.transport_flux(frames * mask, axis)
    masked = vel.transport_flux(frames, axis, mask=mask)
    for name in ("flux", "line_column", "velocity", "displacement"):
        np.testing.assert_array_equal(getattr(masked, name), getattr(plain, name))
    with pytest.raises(ValueError, match="mask must have the frames' shape"):
        vel.transport_flux(frames, axis, mask=mask[1:])
    frames[4, 2, 2] = np.nan  # refused also where the mask leaves the pixel out
    mask[2, 2] = False
    with pytest.raises(ValueError, match=r"frames must be finite \(replace NaN pixels"):
        vel.transport_flux(frames, axis, mask=mask)


@pytest.mark.parametrize("seed", [1, 2])
def test_surface_rate_agrees_with_the_pipelines_surface_flux(ref, seed):
    c, sig, vn, dl = fc.surface_case(seed)
    got = flux.surface_rate(c, sig, vn, dl)
    # The frozen numpy numbers, and the pipeline's function as it is now
    # (it calls qogi.measure.flux after the merge).
    _close(got.rate, ref[f"sf_{seed}_rate"], "rate", rtol=1e-12, atol=0)
    np.testing.assert_array_equal(got.samples, ref[f"sf_{seed}_pixels"])
    assert got.column_variance == pytest.approx(float(ref[f"sf_{seed}_column_variance"]), rel=1e-12)
    sf = _surface_flux(c, sig, vn, dl)
    _close(got.rate, sf.rate, "rate vs _surface_flux", rtol=1e-12, atol=0)
    np.testing.assert_array_equal(got.samples, sf.pixels)
    assert got.column_variance == pytest.approx(sf.column_variance, rel=1e-12)
    assert np.isnan(got.rate[3])  # the frame without any column


def test_surface_rate_of_an_advected_gaussian_plume_is_its_release_rate():
    # c(y) = Q / (u sqrt(2 pi) s) exp(-y^2 / 2 s^2) carried at u across a
    # straight surface: the rate is Q (midpoint rule over +-6 s: < 1e-8);
    # the same in mol/m2 with CH4's molar mass; reversed normal: -Q.
    Q, u, s = 0.02, 1.5, 0.3
    y = np.linspace(-6 * s, 6 * s, 241)
    dl = np.full(y.size, y[1] - y[0])
    c = np.tile(Q / (u * np.sqrt(2 * np.pi) * s) * np.exp(-0.5 * (y / s) ** 2), (4, 1))
    r = flux.surface_rate(c, None, u, dl)
    np.testing.assert_allclose(r.rate, Q, rtol=1e-8)
    assert r.column_variance == 0.0
    m = _engine.molar_mass("CH4")
    np.testing.assert_allclose(
        flux.surface_rate(c / m, np.full(c.shape, 1e-3), u, dl, molar_mass_kg_mol=m).rate,
        Q,
        rtol=1e-8,
    )
    np.testing.assert_allclose(flux.surface_rate(c, None, -u, dl).rate, -Q, rtol=1e-8)
    assert np.all(flux.surface_rate(c, None, 0.0, dl).rate == 0)


def test_surface_rate_refuses_bad_input_naming_the_argument():
    c = np.ones((3, 5))
    with pytest.raises(ValueError, match="length_m"):
        flux.surface_rate(c, None, 1.0, np.ones(4))
    with pytest.raises(ValueError, match="column_sigma"):
        flux.surface_rate(c, np.ones((3, 4)), 1.0, np.ones(5))
    with pytest.raises(ValueError, match="normal_velocity"):
        flux.surface_rate(c, None, np.ones((2, 5)), np.ones(5))
    with pytest.raises(ValueError, match="column must be"):
        flux.surface_rate(np.ones(5), None, 1.0, np.ones(5))
    with pytest.raises(ValueError, match="molar_mass"):
        flux.surface_rate(c, None, 1.0, np.ones(5), molar_mass_kg_mol=-1.0)


def test_max_difference_to_numpy_is_reported(ref):
    """Not a check: prints the largest relative difference to the frozen
    numpy outputs (for the port's record)."""
    worst = 0.0
    for name, seed, axis, src, kind in fc.TRANSPORT_CASES:
        frames = fc.turned(fc.puffing_plume(seed), axis)
        tf = vel.transport_flux(
            frames, axis, src, intervals=fc.intervals(kind, frames.shape[0], seed)
        )
        for f in ("flux", "velocity", "displacement"):
            a, b = getattr(tf, f), ref[f"tf_{name}_{f}"]
            ok = np.isfinite(b) & (b != 0)
            worst = max(worst, float(np.max(np.abs(a[ok] / b[ok] - 1), initial=0.0)))
    print(f"\nmax relative difference of the transport flux to numpy: {worst:.2e}")
    assert worst < TRANSPORT_RTOL
