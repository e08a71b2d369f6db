"""What a field team reports: units, saved settings, tables, the PDF report,
and the detection limit (issue 22)."""

import hashlib
import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pytest

import qogi
from qogi import synth, units
from qogi.errors import UsageError
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.config import load_settings
from qogi.pipeline.config_io import dumps_toml
from qogi.pipeline.surfaces import Region, Surface
from qogi.synth import render

M_CH4 = 16.0425e-3  # kg/mol (12.0107 + 4 x 1.00794)
SURFACE = Surface([(100, 207), (220, 207)], name="S1")


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "qogi", *args], capture_output=True, check=False, text=True
    )


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """A 1 s lab release (15 frames) and its quantification."""
    p = tmp_path_factory.mktemp("lab") / "lab.h5"
    render.synthesize("lab-ch4-5slpm-gf320", p, duration_s=1.0, seed=2)
    cfg = QuantifyConfig(species=["CH4"], source=(159.5, 227.0))
    res = quantify(qogi.open_recording(p), [SURFACE], cfg, keep_maps=True)
    return p, res


# -- units --------------------------------------------------------------------


def test_rate_units_against_hand_values():
    # 1 kg/h of CH4 is 1 / 0.0160425 = 62.3344 mol/h; an ideal gas at 20 C and
    # 1 atm takes 8.314462618 x 293.15 / 101325 = 0.0240550 m3/mol, so
    # 1.499447 m3/h = 24.9908 L/min = 52.9527 ft3/h (0.3048^3 m3 per ft3),
    # and 1.270864 thousand ft3 per day.
    assert units.convert(1.0, "SLPM", M_CH4) == pytest.approx(24.9908, rel=2e-5)
    assert units.convert(1.0, "scfh", M_CH4) == pytest.approx(52.9527, rel=2e-5)
    assert units.convert(1.0, "mcf/day", M_CH4) == pytest.approx(1.270864, rel=2e-5)
    assert units.convert(2.0, "g/h") == 2000.0
    assert units.convert(2.0, "kg/day") == 48.0
    assert units.convert(1.0, "t/year") == pytest.approx(8.76)  # 8760 h, 1000 kg/t
    assert units.convert(3600.0, "kg/s") == pytest.approx(1.0)
    # Arrays and NaN pass through; aliases are accepted, unknown units refused.
    out = units.convert(np.array([1.0, np.nan]), "tpy")
    assert out[0] == pytest.approx(8.76) and np.isnan(out[1])
    assert units.parse_unit("slpm") == "SLPM" and units.parse_unit("MCFD") == "mcf/day"
    with pytest.raises(UsageError, match=r"unknown rate unit.*kg/h"):
        units.parse_unit("furlongs/fortnight")
    with pytest.raises(UsageError, match="molar mass"):
        units.convert(1.0, "scfh")


def test_slpm_agrees_with_the_simulators_own_conversion():
    # The engine (C++) converts a release's SLPM into kg/s on its own; qogi.units
    # must give the same SLPM back.
    rel = synth.Release(rate=5.0, rate_unit="SLPM", composition={"CH4": 1.0})
    kg_h = rel.emission_rate_kg_s()["CH4"] * 3600.0
    assert units.convert(kg_h, "SLPM", M_CH4) == pytest.approx(5.0, rel=1e-4)


def test_result_reports_in_the_chosen_unit(lab):
    _, res = lab
    r = res.total("CH4")
    res.units = "g/h"
    try:
        assert f"{r.mean_kg_h * 1000:.4g} g/h" in res.summary()
        d = res.to_dict()
        sp = d["surfaces"][0]["species"]["CH4"]
        assert d["units"] == "g/h"
        assert sp["mean"] == pytest.approx(r.mean_kg_h * 1000)
        assert sp["ci90"][1] == pytest.approx(r.ci90_kg_h[1] * 1000)
        with pytest.raises(UsageError):
            res.units = "stone/h"
    finally:
        res.units = "kg/h"


# -- settings -----------------------------------------------------------------


def test_config_round_trips_through_dict_and_toml(tmp_path):
    cfg = QuantifyConfig(
        species=["CH4", "CO2"],
        gas_temperature=330.25,
        velocity="wind",
        wind_speed_m_s=0.1 + 0.2,
        background=Region(3, 4, 30, 40),
        source=(159.5, 227.0),
        frames=(2, 9),
        composition={"CH4": 0.5, "CO2": 0.5},
        sigma_m=0.0123456789012345,
        pair_stride=2,
        flux_level=False,
    )
    assert QuantifyConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg
    cfg.to_toml(tmp_path / "s.toml", [SURFACE], "scfh")
    back = load_settings(tmp_path / "s.toml")
    assert back.config == cfg and back.units == "scfh"
    assert back.surfaces[0].points == SURFACE.points and back.surfaces[0].name == "S1"
    assert QuantifyConfig.from_toml(tmp_path / "s.toml") == cfg
    # A typo must not silently become a default.
    (tmp_path / "bad.toml").write_text(dumps_toml(cfg).replace("velocity =", "velocty ="))
    with pytest.raises(UsageError, match=r"unknown setting.*velocty"):
        load_settings(tmp_path / "bad.toml")
    (tmp_path / "bad2.toml").write_text("species = ['CH4'\n")
    with pytest.raises(UsageError, match=r"bad2.toml"):
        load_settings(tmp_path / "bad2.toml")


def test_replayed_settings_give_bit_identical_rates(lab, tmp_path):
    path, res = lab
    res.to_json(tmp_path / "r.json")
    s = load_settings(tmp_path / "r.json")
    again = quantify(qogi.open_recording(path), s.surfaces, s.config)
    a, b = res.total("CH4"), again.total("CH4")
    assert a.rate_kg_s.tobytes() == b.rate_kg_s.tobytes()
    assert a.mean_kg_h == b.mean_kg_h and a.ci90_kg_h == b.ci90_kg_h


# -- tables -------------------------------------------------------------------


def test_dataframes_hold_the_series_and_the_summary(lab):
    pd = pytest.importorskip("pandas")
    _, res = lab
    r = res.total("CH4")
    df = res.to_dataframe()
    assert list(df.columns) == ["surface", "species", "time_s", "rate_kg_h", "rate", "pixels_used"]
    assert len(df) == len(r.time_s) == 15
    np.testing.assert_array_equal(df["rate_kg_h"].to_numpy(), r.rate_kg_h)
    np.testing.assert_array_equal(df["time_s"].to_numpy(), r.time_s)
    assert set(df["surface"]) == {"S1"} and df.attrs["units"] == "kg/h"
    sm = res.to_dataframe(summary=True)
    assert len(sm) == 1 and sm.loc[0, "mean_kg_h"] == r.mean_kg_h
    assert sm.loc[0, "ci90_low"] == r.ci90_kg_h[0] and sm.loc[0, "truth_kg_h"] == r.truth_kg_h
    assert isinstance(sm, pd.DataFrame)


def test_xarray_dataset_has_surface_species_time(lab):
    pytest.importorskip("xarray")
    _, res = lab
    ds = res.to_xarray()
    assert dict(ds["rate_kg_h"].sizes) == {"surface": 1, "species": 1, "time": 15}
    np.testing.assert_array_equal(
        ds["rate_kg_h"].sel(surface="S1", species="CH4").values, res.total("CH4").rate_kg_h
    )
    assert float(ds["mean_kg_h"].sel(surface="S1", species="CH4")) == res.total("CH4").mean_kg_h


def test_missing_pandas_is_said_clearly(lab, monkeypatch):
    _, res = lab
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match="pip install pandas"):
        res.to_dataframe()


def test_repr_says_what_it_is(lab):
    _, res = lab
    text = repr(res)
    assert text.startswith("<qogi.Result lab.h5: 1 surface(s), 15 frames")
    assert "S1 CH4" in text and "kg/h" in text


# -- command line and report --------------------------------------------------


@pytest.mark.slow  # five runs of the command line, each a new process and a quantify
def test_cli_units_json_to_stdout_summary_csv_report_and_replay(lab, tmp_path):
    path, _ = lab
    out = tmp_path / "out"
    r = run(
        "quantify",
        str(path),
        "--surface",
        "100,207,220,207",
        "--source",
        "159.5,227",
        "--units",
        "scfh",
        "--json",
        "-",
        "--csv",
        str(out) + ".csv",
        "--save-config",
        str(tmp_path / "s.toml"),
        "--report",
        str(tmp_path / "leak.pdf"),
        "-q",
    )
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)  # standard output is the JSON alone
    assert d["units"] == "scfh" and "scfh" in r.stderr  # the summary went to stderr
    sp = d["surfaces"][0]["species"]["CH4"]
    assert sp["mean"] == pytest.approx(units.convert(sp["mean_kg_h"], "scfh", M_CH4), rel=1e-5)
    rows = (tmp_path / "out.summary.csv").read_text().splitlines()
    assert rows[0].startswith("surface,species,units,mean,ci90_low,ci90_high,detection_limit")
    assert rows[1].startswith("S1,CH4,scfh,") and "20 C (68 F)" in rows[1]
    assert "rate_scfh" in (tmp_path / "out.csv").read_text().splitlines()[0]
    # Replay from the result JSON and from the saved TOML: the same rates;
    # a flag given explicitly overrides the file.
    (tmp_path / "r.json").write_text(r.stdout)
    for src in ("r.json", "s.toml"):
        r2 = run(
            "quantify",
            str(path),
            "--config",
            str(tmp_path / src),
            "--units",
            "g/h",
            "--json",
            str(tmp_path / f"again_{src}.json"),
            "-q",
        )
        assert r2.returncode == 0, r2.stderr
        d2 = json.loads((tmp_path / f"again_{src}.json").read_text())
        assert d2["units"] == "g/h" and d2["config"] == d["config"]
        assert d2["surfaces"][0]["species"]["CH4"]["rate_kg_h"] == sp["rate_kg_h"]
    r3 = run(
        "quantify",
        str(path),
        "--config",
        str(tmp_path / "s.toml"),
        "--background",
        "percentile",
        "--frames",
        "0:5",
        "--json",
        str(tmp_path / "o.json"),
        "-q",
    )
    assert r3.returncode == 0, r3.stderr
    cfg3 = json.loads((tmp_path / "o.json").read_text())["config"]
    assert (
        cfg3["background"] == "percentile"
        and cfg3["frames"] == [0, 5]
        and cfg3["source"] == [159.5, 227.0]
    )


@pytest.mark.skipif(
    shutil.which("pdftotext") is None or shutil.which("pdftoppm") is None,
    reason="poppler-utils (pdftotext, pdftoppm) not installed: "
    "scripts/setup_system.sh installs them",
)
def test_pdf_report_pages_render_and_say_what_matters(lab, tmp_path):
    from qogi.apps.report import write_report

    path, res = lab
    res.warnings.add("test-warning", "a warning the report must show", surface="S1")
    n_warnings = len(res.warnings)  # the pipeline's own (a short record) and this one
    try:
        pdf = tmp_path / "leak.pdf"
        write_report(res, pdf)
    finally:
        res.warnings.pop()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".qogi-tmp-")]
    text = subprocess.run(
        ["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True, check=True
    ).stdout
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    r = res.total("CH4")
    for needle in (
        "qogi emission-rate report",
        "lab.h5",
        sha,
        f"qogi {qogi.__version__}",
        "Scene",
        "Emission rate",
        "Surfaces and species",
        "Uncertainty budget",
        "velocity",
        "column density",
        "temporal",
        f"Warnings ({n_warnings})",
        "test-warning",
        "Settings",
        "gas_temperature = ambient",
        "distance_m = 1.5 (the recording's)",
        "source = (159.5, 227.0)",
        f"{r.mean_kg_h:.4g}",
        "Detection limit",
        "noise-equivalent",
        "20 C (68 F)",
        # The audit record (issue 28): the run's UTC start; no capture time in a synthetic file.
        f"run {res.audit['run_started_utc']}",
        "recorded unknown (UTC)",
        # Page 3 (issue 28 item 4): where in the frame the camera sees the gas.
        "qogi emission-rate report (detectability)",
        "Minimum-detectable column: CH4",
        # ... and where the scene sits in the operating envelope (issue 28 item 5)
        "Operating point and probability of detection",
        "expected",
        "PoD at",
    ):
        assert needle in text, needle
    # the operating point's figures are the result's, as printed
    op = res.surfaces[0].species["CH4"].operating_point
    assert f"{op['delta_T_K']:+.1f}" in text and f"{op['snr']:.3g}" in text
    subprocess.run(["pdftoppm", "-r", "40", "-png", str(pdf), str(tmp_path / "page")], check=True)
    pages = sorted(tmp_path.glob("page-*.png"))
    assert len(pages) == 3
    import cv2

    img = cv2.imread(str(pages[0]))
    assert img.shape[0] > img.shape[1]  # A4 portrait
    assert (img < 128).mean() > 0.05  # the scene and plot are drawn
    third = cv2.imread(str(pages[2]))
    assert (third.std(axis=2) > 20).mean() > 0.05  # the map is drawn, in colour


# -- detection limit ----------------------------------------------------------


def test_noise_equivalent_column_is_the_thin_limit_signal():
    # One channel: NEC = NETD dB/dT(T_bg) / (dL/dc), with dL/dc from the
    # forward model between two small columns (independent of the probe).
    from qogi.physics.forward import forward_model
    from qogi.pipeline.detection import noise_equivalent_column

    cam = qogi.camera_preset("gf320")
    model = forward_model(cam.channels, ["CH4"])
    nec = noise_equivalent_column(model, "CH4", 0.015, 285.15, 294.45, 294.45)
    x = np.array([[2e-5], [4e-5]])
    L = model.band_radiance(x, 294.45, 0.05, 294.45, 285.15)[:, 0]
    col = model.column_density(x, 294.45, 0.05, 294.45)["CH4"]
    slope = abs(L[1] - L[0]) / (col[1] - col[0])
    assert nec == pytest.approx(
        0.015 * cam.channels[0].band_radiance_derivative(285.15) / slope, rel=0.01
    )
    # No contrast (gas at the background's temperature): nothing is detectable.
    assert noise_equivalent_column(model, "CH4", 0.015, 294.45, 294.45, 294.45) > 1e3 * nec


def test_zeng_morris_fit_values():
    from qogi.pipeline.detection import zeng_morris_g_h

    # 18.41 x 10^-1.094 x 5^2 = 36.98 g/h at dT = 10 K, 5 m.
    assert zeng_morris_g_h(10.0, 5.0) == pytest.approx(18.41 * 10**-1.094 * 25)
    assert zeng_morris_g_h(-10.0, 5.0) == zeng_morris_g_h(10.0, 5.0)


def _band_recording(
    peak_fraction,
    *,
    bg_K=280.0,
    amb_K=295.0,
    dist=5.0,
    sigma_px=4.0,
    frames=15,
    width=120,
    height=60,
    seed=0,
):
    """An exact-truth scene: a static vertical band of CH4 (Gaussian across,
    depth = width) rendered by the forward model over a plate, with seeded
    NETD noise. Returns the recording and the truth per m/s of normal speed
    [kg/h]: sum of the columns across the band x pixel size."""
    import dataclasses

    from qogi.io.recording import Recording, Scene
    from qogi.physics.forward import forward_model
    from qogi.physics.radiometry import radiance_to_temperature

    cam = dataclasses.replace(qogi.camera_preset("gf320"), width=width, height=height)
    model = forward_model(cam.channels, ["CH4"])
    pix = dist * cam.ifov_rad
    x = np.arange(width)
    frac = peak_fraction * np.exp(-0.5 * ((x - width / 2) / sigma_px) ** 2)
    L = model.band_radiance(frac[:, None], amb_K, sigma_px * pix, amb_K, bg_K)[:, 0]
    col = np.asarray(model.column_density(frac[:, None], amb_K, sigma_px * pix, amb_K)["CH4"])
    t_img = radiance_to_temperature(L[None, None, None, :], cam.channels)[0, 0, 0]
    rng = np.random.default_rng(seed)
    stack = np.broadcast_to(t_img, (frames, 1, height, width)) + rng.normal(
        0.0, cam.netd_K, (frames, 1, height, width)
    )
    scene = Scene(
        distance_m=dist, ambient_temperature_K=amb_K, pressure_Pa=101325.0, species=("CH4",)
    )
    rec = Recording.from_arrays(stack, quantity="radiometric_temperature", camera=cam, scene=scene)
    return rec, float(col.sum()) * pix * 3600.0


def test_detection_limit_matches_the_lowest_rate_the_pipeline_detects():
    # A sweep of rates through one surface at a known normal speed (1 m/s).
    # "Actually detected": the result says so (its mean at or above the
    # limit). Before the plume's faint wings were kept (signed columns below
    # the per-pixel test, issue 28) this test took "a rate > 0 in >= 95 % of
    # the frames" (a frame's rate was > 0 only where a pixel passed the
    # test); now a frame's rate is an unbiased noisy sum, and the mean, no
    # longer read low near the limit, switches at it. Measured: the limit
    # 0.0036-0.0040 kg/h on every run whose time-averaged contrast shows the
    # band; detected from 0.0041 kg/h (1.1x the limit; before: 0.0062, 1.7x).
    surf = [Surface([(20, 30), (100, 30)], name="S")]
    cfg = QuantifyConfig(species=["CH4"], velocity="wind", wind_speed_m_s=1.0)
    runs = []
    for pf in (1e-4, 2e-4, 3e-4, 4e-4, 6e-4, 1e-3):
        rec, truth = _band_recording(pf)
        r = quantify(rec, surf, cfg).total("CH4")
        runs.append((truth, r))
    lowest = min(truth for truth, r in runs if r.detected)
    assert all(r.detected for truth, r in runs if truth >= lowest)  # one switch
    for truth, r in runs:
        x = r.detection_limit_kg_h
        assert r.detection["width_from"] == "time-averaged contrast"
        assert lowest / 1.5 <= x <= 1.5 * lowest, (x, lowest)
        if truth >= 1.5 * x:  # well above the limit: a number
            assert r.detected and "not detected" not in r.text()
        if truth <= x / 1.5:  # well below: "not detected, < X", and X is above the truth
            up = r.upper_limit_kg_h
            assert r.detected is False and up >= x and up > truth
            assert r.text().startswith(f"not detected, < {up:.3g} kg/h")
    assert any(truth >= 1.5 * r.detection_limit_kg_h for truth, r in runs)
    assert any(truth <= r.detection_limit_kg_h / 1.5 for truth, r in runs)
    # No bias at low signal (issue 28 item 2): from half the limit up, the
    # mean reads the truth (measured -3 ... +0 %; before, with the wings
    # zeroed, -80 % at half the limit, -34 % at 1.1x, -19 % at 1.7x).
    for truth, r in runs:
        if truth >= 0.5 * r.detection_limit_kg_h:
            assert abs(r.mean_kg_h / truth - 1.0) <= 0.1, (truth, r.mean_kg_h)


def test_detection_limit_without_any_sign_of_gas_is_an_upper_bound():
    # No frame and not even the time average shows the band: the limit takes
    # the surface's whole length as the plume's width, a bound above the truth.
    rec, truth = _band_recording(2e-5)
    r = quantify(
        rec,
        [Surface([(20, 30), (100, 30)])],
        QuantifyConfig(species=["CH4"], velocity="wind", wind_speed_m_s=1.0),
    ).total("CH4")
    assert r.detected is False and r.detection["width_from"].startswith("surface length")
    assert r.detection_limit_kg_h > truth
    d = r.to_dict()
    assert d["detected"] is False and d["detection_limit_kg_h"] == r.detection_limit_kg_h
    # Far below the limit the bound said is the limit (the interval lies under it).
    assert d["upper_limit_kg_h"] == r.detection_limit_kg_h
    assert r.text().startswith(f"not detected, < {r.detection_limit_kg_h:.3g} kg/h")


def test_not_detected_is_never_said_below_a_truth_just_above_the_limit():
    # Issue 28: "not detected, < X" is never said of a truth above X. The
    # decision compares the mean with the limit, and a truth just above the
    # limit can read below it (with the plume's wings zeroed it did in 6 of 27
    # runs of steady bands 0.55-2.2x the limit, seeds 0-2: 4.1 g/h read
    # 2.5-2.7 g/h against limits of 3.4-4.0; with them kept, the mean's noise
    # still can). The bound said is the larger of the limit and the
    # interval's upper end (SpeciesRate.upper_limit_kg_h).
    surf = [Surface([(20, 30), (100, 30)], name="S")]
    cfg = QuantifyConfig(species=["CH4"], velocity="wind", wind_speed_m_s=1.0)
    said = 0
    for seed in (0, 1):
        for pf in (3.0e-4, 3.4e-4, 4.0e-4):
            rec, truth = _band_recording(pf, seed=seed)
            res = quantify(rec, surf, cfg)
            r = res.total("CH4")
            if r.detected is not False:
                assert r.upper_limit_kg_h is None
                continue
            said += 1
            x = r.upper_limit_kg_h
            assert x >= r.detection_limit_kg_h and x >= r.ci90_kg_h[1]
            assert x > truth, (truth, r.detection_limit_kg_h, r.ci90_kg_h)
            assert r.text().startswith(f"not detected, < {x:.3g} kg/h")
            assert res.to_dict()["surfaces"][0]["species"]["CH4"]["upper_limit_kg_h"] == x
    assert said >= 2


def test_the_bound_of_a_rate_not_detected_is_the_limit_or_the_intervals_end():
    from qogi.pipeline.result import SpeciesRate

    def rate(mean, ci, limit):
        return SpeciesRate(
            species="CH4",
            time_s=np.zeros(1),
            rate_kg_s=np.array([mean / 3600]),
            mean_kg_h=mean,
            ci90_kg_h=ci,
            n_frames=1,
            molar_mass_kg_mol=0.016,
            uncertainty_terms_kg_h={},
            dominant_uncertainty="temporal",
            pixels_used=np.zeros(1, int),
            detection_limit_kg_h=limit,
        )

    # A truth of 4.1 g/h read 2.7 [1.1 .. 6.3] against a limit of 3.7 g/h:
    # "< 3.7" would have been false, "< 6.3" holds.
    r = rate(0.0027, (0.0011, 0.0063), 0.0037)
    assert r.detected is False and r.upper_limit_kg_h == 0.0063
    assert r.text("g/h") == "not detected, < 6.3 g/h"
    assert rate(0.0005, (0.0001, 0.0020), 0.0037).upper_limit_kg_h == 0.0037
    assert rate(0.0005, (0.0001, math.nan), 0.0037).upper_limit_kg_h == 0.0037
    assert rate(0.0050, (0.0030, 0.0070), 0.0037).upper_limit_kg_h is None
    assert rate(0.0050, (0.0030, 0.0070), None).upper_limit_kg_h is None
