"""The error model (issue 28, item 3): its features, the calibrated interval,
the fit (scripts/fit_error_model.py) on rows whose truth is known, and its
use in the pipeline's intervals."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from qogi.pipeline import error_model
from qogi.pipeline.error_model import FEATURES, Z90, ErrorModel, calibrated_interval

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import fit_error_model as fit


def _feats(mean_kg_h=1.0, detection_limit_kg_h=0.1, detected=True, **kw):
    base = dict(
        speed_m_s=1.0,
        pixel_m=0.01,
        frame_rate_hz=10.0,
        duration_s=10.0,
        background="beside-surface",
        self_check_failed=False,
    )
    base.update(kw)
    scene = error_model.scene_features(**base)
    return error_model.features(mean_kg_h, detection_limit_kg_h, detected, scene)


def test_the_features_are_what_the_run_measures_and_none_where_the_model_does_not_apply():
    f = _feats()
    # 1 m/s over 1 cm pixels at 10 Hz: 10 px per frame, inside the flow's range
    assert f == pytest.approx(
        dict(
            ln_snr=math.log(10.0),
            flow_range=0.0,
            self_check_failed=0.0,
            percentile_background=0.0,
            short_record=0.0,
        )
    )
    # below 1 px between a pair's frames, above 64
    assert _feats(speed_m_s=0.025)["flow_range"] == pytest.approx(math.log(4.0))
    assert _feats(speed_m_s=0.025, pair_stride=4)["flow_range"] == 0.0
    assert _feats(speed_m_s=12.8)["flow_range"] == pytest.approx(math.log(2.0))
    assert _feats(duration_s=1.5)["short_record"] == pytest.approx(math.log(2.0))
    assert _feats(background="percentile")["percentile_background"] == 1.0
    assert _feats(self_check_failed=True)["self_check_failed"] == 1.0
    assert _feats(detected=False) is None
    assert _feats(detected=None) is None  # no decision (no limit, or unbounded)
    assert _feats(mean_kg_h=-0.5) is None
    assert _feats(speed_m_s=0.0) is None
    assert _feats(speed_m_s=math.nan) is None


def test_the_calibrated_interval_is_the_budgets_widened_in_quadrature_about_the_shifted_centre():
    budget = (0.8, 1.25)
    assert calibrated_interval(1.0, budget, 0.0, 0.0) == pytest.approx(budget)
    lo, hi = calibrated_interval(1.0, budget, 0.0, 0.2)
    s_up, s_lo = math.log(1.25) / Z90, math.log(1 / 0.8) / Z90
    assert hi == pytest.approx(math.exp(Z90 * math.hypot(s_up, 0.2)))
    assert lo == pytest.approx(math.exp(-Z90 * math.hypot(s_lo, 0.2)))
    # a rate read 20 % low (bias ln 0.8): the model's interval moves up by
    # 1/0.8, and the calibrated one is its hull with the budget's (it only
    # ever widens: a scene unlike the envelope keeps its own budget)
    lo2, hi2 = calibrated_interval(1.0, budget, math.log(0.8), 0.0)
    assert (lo2, hi2) == pytest.approx((0.8, 1.5625))
    # read 20 % high: the low side grows
    assert calibrated_interval(1.0, budget, math.log(1.2), 0.0) == pytest.approx((0.8 / 1.2, 1.25))
    # a side that reaches zero stays; an unbounded one too
    assert calibrated_interval(1.0, (-0.1, 2.0), 0.0, 0.3)[0] == -0.1
    assert math.isinf(calibrated_interval(1.0, (0.5, math.inf), 0.0, 0.3)[1])


def test_a_model_file_of_another_shape_is_refused_with_the_fix():
    d = error_model.load().to_dict()
    assert ErrorModel.from_dict(d).bias == error_model.load().bias
    with pytest.raises(ValueError, match="fit_error_model"):
        ErrorModel.from_dict({**d, "features": ["ln_snr"]})
    with pytest.raises(ValueError, match="coefficients"):
        ErrorModel((0.0,), (0.0,), {})


def _synthetic_rows(n, seed, bias_coef, spread_coef):
    """Rows whose ln(rate / truth) is bias(x) + spread(x) N(0, 1), with a
    budget interval of +-10 % (far too narrow where the spread is large)."""
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n):
        feats = {
            "ln_snr": rng.uniform(0.0, 6.0),
            "flow_range": rng.choice([0.0, 0.0, rng.uniform(0, 2)]),
            "self_check_failed": float(rng.random() < 0.4),
            "percentile_background": float(rng.random() < 0.6),
            "short_record": rng.choice([0.0, math.log(2.0)]),
        }
        x = np.array([1.0] + [feats[k] for k in FEATURES])
        e = x @ bias_coef + math.exp(x @ spread_coef) * rng.standard_normal()
        mean = 1.0
        rows.append(
            dict(
                block="b",
                seed=seed,
                truth=mean / math.exp(e),
                mean=mean,
                lo=mean / 1.1,
                hi=mean * 1.1,
                features=feats,
            )
        )
    return rows


def test_the_fit_recovers_a_known_model_and_covers_90_percent_of_fresh_rows():
    pytest.importorskip("scipy")
    bias = np.array([-0.3, 0.05, -0.5, 0.0, -0.1, -0.1])
    spread = np.array([-1.0, -0.15, 0.4, 0.3, 0.0, 0.2])
    rows = _synthetic_rows(1500, 0, bias, spread)
    X, e = fit.design(rows), fit.log_errors(rows)
    b = fit.fit_bias(X, e)
    a = fit.fit_spread(X, fit.needed_spread(rows, X @ b))
    assert b == pytest.approx(bias, abs=0.08)
    model = ErrorModel(tuple(b), tuple(a), {})
    held = fit.coverage(model, _synthetic_rows(1500, 1, bias, spread))["all"]
    assert held["budget"] < 0.5  # the +-10 % budget alone misses most
    assert 0.87 <= held["calibrated"] <= 0.93


def test_the_packaged_model_states_where_it_was_fitted_and_what_it_covered_held_out():
    d = json.loads(
        (Path(error_model.__file__).parents[1] / "data" / "error_model.json").read_text()
    )
    prov = d["provenance"]
    assert "envelope" in prov["fitted_on"] and prov["script"] == "scripts/fit_error_model.py"
    held = prov["coverage_held_out"]
    assert held is not None and held["all"]["rows"] >= 100
    # issue 28: the calibrated interval's held-out coverage is 90 +- 5 %
    assert abs(held["all"]["calibrated"] - 0.90) <= 0.05


def test_a_detected_rate_carries_the_models_record_and_its_calibrated_interval(tmp_path):
    import qogi
    from qogi.pipeline import QuantifyConfig, quantify
    from qogi.pipeline.surfaces import truth_surfaces
    from qogi.synth import render

    p = tmp_path / "lab.h5"
    render.synthesize("lab-ch4-5slpm-gf320", p, duration_s=20 / 15, seed=5)
    rec = qogi.open_recording(p)
    surf, source = truth_surfaces(rec, heights_m=[0.04, 0.08], half_width_px=40)
    res = quantify(rec, surf, QuantifyConfig(source=source))
    model = error_model.load()
    seen = 0
    for s in res.surfaces:
        r = s.species["CH4"]
        if r.detected is not True:
            assert r.error_model is None
            continue
        seen += 1
        rec_ = r.error_model
        bias, spread = model.expected(rec_["features"])
        assert rec_["expected_error"] == pytest.approx(math.expm1(bias))
        assert r.ci90_kg_h == pytest.approx(
            calibrated_interval(r.mean_kg_h, rec_["ci90_budget_kg_h"], bias, spread)
        )
        assert r.uncertainty_terms_kg_h["error model"] == pytest.approx(abs(r.mean_kg_h) * spread)
        assert rec_["features"]["ln_snr"] == pytest.approx(
            math.log(r.mean_kg_h / r.detection_limit_kg_h)
        )
    assert seen
    d = json.loads(res.to_json())
    assert all("error_model" in s["species"]["CH4"] for s in d["surfaces"])
    # issue 28 item 5: every rate says where in the envelope it was measured,
    # with the probability of detection there
    for s in res.surfaces:
        r = s.species["CH4"]
        op = r.operating_point
        det = r.detection
        assert op["distance_m"] == pytest.approx(rec.scene.distance_m)
        assert op["delta_T_K"] == pytest.approx(
            det["gas_temperature_K"] - det["background_temperature_K"]
        )
        assert op["speed_m_s"] == pytest.approx(det["velocity_m_s"]) and op["speed_m_s"] > 0
        assert op["snr"] == pytest.approx(r.mean_kg_h / r.detection_limit_kg_h)
        assert op["expected_error"] == (r.error_model or {}).get("expected_error")
        assert 0 < op["pod_50_kg_h"] < op["pod_90_kg_h"]
        assert 0.0 <= op["pod_at_mean"] <= 1.0
        where = error_model.scene_features(
            det["velocity_m_s"],
            res.info["pixel_m"],
            res.info["frame_rate_hz"],
            r.n_frames / res.info["frame_rate_hz"],
            "percentile"
            if "percentile" in str((res.info.get("background_choice") or {}).get("method"))
            else "",
            any(w.surface == s.surface.name and w.code in _self_codes() for w in res.warnings),
            int(res.info.get("pair_stride") or 1),
        )
        assert model.probability(op["pod_90_kg_h"], r.detection_limit_kg_h, where) == (
            pytest.approx(0.9)
        )
    assert all("operating_point" in s["species"]["CH4"] for s in d["surfaces"])
    op = res.surfaces[0].species["CH4"].operating_point
    assert f"detected 90 % of the time from {op['pod_90_kg_h']:.3g} kg/h here" in res.summary()


def _self_codes():
    from qogi.pipeline import selfchecks

    return set(selfchecks.CODES.values())


def _pod_rows(n, seed, slope, offset):
    """Rows detected with probability logistic(slope ln(truth / limit) -
    offset . [1, x]) over a spread of truths about the limit."""
    from qogi.pipeline.error_model import SCENE_FEATURES

    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        where = {
            "flow_range": rng.choice([0.0, 0.0, rng.uniform(0, 2)]),
            "self_check_failed": float(rng.random() < 0.4),
            "percentile_background": float(rng.random() < 0.5),
            "short_record": rng.choice([0.0, math.log(2.0)]),
        }
        t = rng.uniform(-4.0, 4.0)
        z = slope * t - np.array([1.0] + [where[k] for k in SCENE_FEATURES]) @ offset
        rows.append(
            dict(
                scene=f"s{i % 40}",
                block="b",
                truth=math.exp(t) * 0.01,
                limit=0.01,
                where=where,
                detected=bool(rng.random() < 1.0 / (1.0 + math.exp(-z))),
            )
        )
    return rows


def test_the_probability_of_detection_fit_recovers_a_known_logistic_and_inverts():
    slope, offset = 2.0, np.array([-1.0, 0.8, 0.3, 0.5, 1.2])
    rows = _pod_rows(20000, 0, slope, offset)
    pod = fit.fit_pod(rows, ridge=0.0)
    assert pod["slope"] == pytest.approx(slope, rel=0.1)
    assert np.array(pod["offset"]) == pytest.approx(offset, abs=0.25)
    model = ErrorModel((0.0,) * 6, (0.0,) * 6, {}, pod)
    where = rows[0]["where"]
    q90 = model.rate_at(0.9, 0.01, where)
    assert model.probability(q90, 0.01, where) == pytest.approx(0.9)
    assert model.probability(q90 * 2, 0.01, where) > 0.9 > model.probability(q90 / 2, 0.01, where)
    assert (
        model.probability(0.0, 0.01, where) == 0.0 and model.probability(1.0, None, where) is None
    )
    check = fit.pod_check(model, _pod_rows(6000, 1, slope, offset))
    # 150 rows per scene: the observed fraction within a few points of the truth
    assert check["within_10_points"] == check["scenes"] == 40
    with pytest.raises(ValueError, match="slope"):
        ErrorModel((0.0,) * 6, (0.0,) * 6, {}, {"slope": -1.0, "offset": list(offset)})


def test_the_packaged_probability_of_detection_states_its_held_out_check():
    model = error_model.load()
    assert model.pod is not None and model.pod["slope"] > 0
    held = model.provenance["pod_held_out"]
    assert held["scenes"] >= 40 and held["rows"] >= 200
    # every scene where the stated probability is more than 10 points off is listed
    assert len(held["gaps"]) == held["scenes"] - held["within_10_points"]
