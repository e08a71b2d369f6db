"""End-to-end accuracy on synthetic releases with exact truth (short versions
of scripts/validate_pipeline.py; the full versions, over ten seeds each, are
in docs/validation.md).

The gas-temperature finding of the thesis, isolated from the velocimetry:
every rate here uses one given speed (velocity="exit"), so the ratio of the
rate from inverted column densities to the rate from the truth's column
densities is the ratio of the column sums along each control surface."""

import json
import subprocess
import sys

import numpy as np
import pytest

import qogi
from qogi import synth
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import Surface, auto_surfaces, plume_image, truth_surfaces
from qogi.synth import render

HEIGHTS_CM = (4, 8, 12)


def _surfaces(rec):
    return truth_surfaces(
        rec, heights_m=[h / 100 for h in HEIGHTS_CM], half_width_px=50 if rec.height == 256 else 40
    )


def _column_ratio(rec, **cfg):
    """Inverted / truth column sum along each surface (same given speed)."""
    surf, source = _surfaces(rec)
    rates = {}
    for mode in ("truth", "inversion"):
        c = dict(cfg) if mode == "inversion" else dict(species=cfg["species"])
        res = quantify(
            rec,
            surf,
            QuantifyConfig(
                column_density=mode, velocity="exit", exit_velocity_m_s=1.0, source=source, **c
            ),
        )
        rates[mode] = np.array([s.species["CH4"].mean_kg_h for s in res.surfaces])
    return rates["inversion"] / rates["truth"], res


@pytest.fixture(scope="module")
def heated_gf320(tmp_path_factory):
    p = tmp_path_factory.mktemp("heated") / "gf320.h5"
    render.synthesize("lab-heated-ch4-55c-gf320", p, duration_s=20 / 15, seed=5, truth_maps=True)
    return qogi.open_recording(p)


@pytest.fixture(scope="module")
def heated_m150(tmp_path_factory):
    p = tmp_path_factory.mktemp("heated") / "m150.h5"
    render.synthesize(
        "lab-heated-ch4-55c-gf320",
        p,
        duration_s=0.2,
        seed=5,
        truth_maps=True,
        camera_name="fast-m150",
    )
    return qogi.open_recording(p)


def _inferred_within_profile_error(what, rec, **cfg):
    """The inverted / truth column ratios with the temperature inferred on the
    mixing line, printed with the line's slope; asserted within the Gaussian
    line-of-sight model's profile error: the columns of these lab plumes read
    8-19 % low with the temperature known or inferred (docs/validation.md),
    against x2-3 with it assumed."""
    ratio, res = _column_ratio(rec, **cfg)
    print(
        f"{what}, temperature inferred: inverted / truth columns",
        np.round(ratio, 3),
        "mixing line",
        res.info.get("mixing_line_K_per_fraction"),
    )
    assert np.all(np.abs(ratio - 1.0) < 0.25), ratio
    return ratio


def test_heated_methane_single_channel_assumed_ambient_overestimates(heated_gf320):
    # 55 C methane in front of a colder background, inverted as if at ambient:
    # the model needs more gas to make the measured (hotter) emission. The
    # thesis found this bias to be several-fold (x7 on its case).
    ratio, _ = _column_ratio(heated_gf320, species=["CH4"], gas_temperature="ambient")
    print("single channel, gas assumed ambient: inverted / truth columns", np.round(ratio, 3))
    assert np.all(ratio > 1.5), ratio


def test_heated_methane_multichannel_infers_the_temperature(heated_m150):
    ratio = _inferred_within_profile_error(
        "four channels", heated_m150, species=["CH4"], gas_temperature="infer"
    )
    # The same pixels with the temperature assumed ambient are far off.
    wrong, _ = _column_ratio(heated_m150, species=["CH4"], gas_temperature="ambient")
    print("four channels, gas assumed ambient:", np.round(wrong, 3))
    assert np.all(np.abs(wrong - 1.0) > 2 * np.abs(ratio - 1.0)), (wrong, ratio)


def test_thesis_case_columns_with_the_temperature_inferred(tmp_path):
    p = tmp_path / "m150.h5"
    render.synthesize("lab-ch4co2-90c-m150", p, duration_s=0.2, seed=6, truth_maps=True)
    rec = qogi.open_recording(p)
    _inferred_within_profile_error(
        "50/50 CH4/CO2 at 90 C",
        rec,
        species=["CH4", "CO2"],
        gas_temperature="infer",
        composition={"CH4": 0.5, "CO2": 0.5},
    )


def test_lab_release_at_15hz_end_to_end(tmp_path):
    # The whole chain on the GF320 lab release at 15 Hz: single-channel
    # inversion, the default velocimetry (fluid flow with the transport flux
    # level), 10 s. Over ten seeds (docs/validation.md) the time-averaged
    # rate reads -12.5 % on average, -6 to -19 % per seed, and the 90 %
    # interval covers the truth in 8 of 10 (coverage is a property of many
    # seeds, measured there): one seed here must be within that spread with a
    # margin.
    p = tmp_path / "gf320.h5"
    render.synthesize("lab-ch4-5slpm-gf320", p, duration_s=10.0, seed=11)
    rec = qogi.open_recording(p)
    surf, source = _surfaces(rec)
    res = quantify(rec, surf, QuantifyConfig(species=["CH4"], source=source))
    assert res.info["flux_level"].startswith("on"), res.info["flux_level"]
    for s in res.surfaces:
        r = s.species["CH4"]
        print(
            s.surface.name,
            f"{100 * r.error_vs_truth:+.1f} %",
            np.round(r.ci90_kg_h, 4),
            r.truth_kg_h,
        )
        assert abs(r.error_vs_truth) < 0.25, (s.surface.name, r.error_vs_truth)
        assert r.ci90_kg_h[0] < r.mean_kg_h < r.ci90_kg_h[1]


WIND = "stack-20kgh-wind6-gf320"


@pytest.fixture(scope="module")
def wind_rec(tmp_path_factory):
    p = tmp_path_factory.mktemp("wind") / "wind.h5"
    render.synthesize(WIND, p, duration_s=5.0, seed=4)
    view, rel = synth.preset_view(WIND), synth.preset_release(WIND)
    fp = view.distance_m * view.ifov_rad
    ex = 0.5 * (view.width_px - 1) + (rel.exit_x_m - view.center_x_m) / fp
    ey = 0.5 * (view.height_px - 1) - (rel.stack_height_m - view.center_z_m) / fp
    return p, (ex, ey)


def test_stack_in_crosswind_end_to_end(wind_rec):
    # The stack in a 6 m/s crosswind at 10 m and 15 Hz: the gas crosses ~28 px
    # per frame, left to right. Vertical surfaces downwind, the exit as the
    # source. The 2-D flows cannot follow that motion (they read it 2-5x
    # slow or backwards), so the flux level comes from the transport of the
    # line-integrated column alone; before that fallback, and with the field's
    # background interpolated across the sky's elevation gradient, the rates
    # came out with the wrong sign. Measured: -4.9 to -5.0 %.
    path, (ex, ey) = wind_rec
    rec = qogi.open_recording(path)
    surf = [Surface([(ex + d, ey - 45), (ex + d, ey + 45)], name=f"{d} px") for d in (50, 100, 150)]
    res = quantify(rec, surf, QuantifyConfig(species=["CH4"], source=(ex, ey)))
    assert res.info["flux_level"].startswith("on"), res.info["flux_level"]
    for s in res.surfaces:
        r = s.species["CH4"]
        print(s.surface.name, f"{100 * r.error_vs_truth:+.1f} %", np.round(r.ci90_kg_h, 2))
        assert abs(r.error_vs_truth) < 0.3, (s.surface.name, r.error_vs_truth)


def test_source_is_detected_for_the_flux_level_when_not_given(wind_rec):
    # Surfaces drawn top to bottom count rightward flow as positive (left-hand
    # normal); without a source the fluid flow alone had no flux level (lab
    # release: -53 to -77 %). The detected source gives it the transport's.
    path, (ex, ey) = wind_rec
    rec = qogi.open_recording(path)
    surf = [Surface([(ex + d, ey - 45), (ex + d, ey + 45)]) for d in (50, 150)]
    res = quantify(rec, surf, QuantifyConfig(species=["CH4"]))
    assert res.info["source"].startswith("detected"), res.info["source"]
    assert res.info["flux_level"].startswith("on"), res.info["flux_level"]
    for s in res.surfaces:
        assert abs(s.species["CH4"].error_vs_truth) < 0.3, s.species["CH4"].error_vs_truth


def test_auto_surfaces_find_the_bent_plume_and_its_source(wind_rec, tmp_path):
    # No surface and no source given: the plume is found in its fluctuations
    # and its departure from a smooth background (the sky's gradient is far
    # larger than the plume's mean contrast), the source at its narrow end.
    # Measured: source within 6 px of the exit, rates -3 %.
    path, (ex, ey) = wind_rec
    rec = qogi.open_recording(path)
    surf, source = auto_surfaces(plume_image(rec), [50, 100, 150], return_source=True)
    assert np.hypot(source[0] - ex, source[1] - ey) < 12, (source, (ex, ey))
    for s in surf:
        (x0, y0), (x1, y1) = s.points[0], s.points[-1]
        assert abs(x1 - x0) < 0.2 * abs(y1 - y0), s.points  # across the wind: vertical
    out = tmp_path / "auto.json"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "qogi",
            "quantify",
            str(path),
            "--auto-surfaces",
            "50,100,150",
            "--json",
            str(out),
            "-q",
        ],
        capture_output=True,
        check=False,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    d = json.loads(out.read_text())
    for s in d["surfaces"]:
        sp = s["species"]["CH4"]
        print(s["name"], sp["mean_kg_h"], sp["truth_kg_h"])
        assert abs(sp["mean_kg_h"] / sp["truth_kg_h"] - 1) < 0.3


def test_auto_surfaces_find_the_lab_plume_and_its_exit(tmp_path):
    # The rising lab plume against a plate: its steady base near the exit
    # fluctuates little but stands out from the plate; the source is its
    # narrow (lower) end. Measured: source within 1 px of the exit (seeds 6, 7).
    p = tmp_path / "lab.h5"
    render.synthesize("lab-ch4-5slpm-gf320", p, duration_s=2.0, seed=6)
    rec = qogi.open_recording(p)
    _, exit_xy = truth_surfaces(rec)
    surf, source = auto_surfaces(plume_image(rec), [20, 60], return_source=True)
    assert np.hypot(source[0] - exit_xy[0], source[1] - exit_xy[1]) < 8, (source, exit_xy)
    for s in surf:
        (x0, y0), (x1, y1) = s.points[0], s.points[-1]
        assert abs(y1 - y0) < 0.35 * abs(x1 - x0), s.points  # across the rise: horizontal
        assert x0 < exit_xy[0] < x1 or x1 < exit_xy[0] < x0
