"""Stage 5, the rate and its uncertainty budget: each surface's and
species' per-frame rates over the run's blocks, their mean and 90 %
interval combining the temporal standard error (with autocorrelation), the
column-density uncertainty, the velocimetry's systematic uncertainty, the
line shape's and the background's; then the checks (``Result.warnings``): a
rate against the surface's orientation or zero while gas crosses it
(interval widened), the record length a 10 % mean needs, evidence that an
assumed gas temperature is wrong (:mod:`qogi.pipeline.hotgas`).

(:mod:`qogi.pipeline.budget_terms` holds the budget terms' physics; this module is the
pipeline's stage that assembles the Result with them.)
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Dict, List, Optional, cast

import numpy as np

from .. import _engine
from . import checks, error_model, selfchecks
from .budget_terms import record_length_advice
from .columns import InvertedColumns
from .detection import (
    detection_limit_from_sums,
    median_background_K,
    min_detectable_column,
    velocity_from_sums,
)
from .error_model import POD_LEVEL, Z90
from .flux_summary import FluxSummary
from .hotgas import check_gas_temperature
from .result import Result, SpeciesRate, SurfaceResult
from .sampling import _bilinear
from .state import RunState

__all__ = [
    "finish",
    "interval90",
    "Systematics",
    "VELOCITY_SYSTEMATIC",
    "COLUMN_SYSTEMATIC",
    "COLUMN_SYSTEMATIC_INFERRED",
]

#: Relative systematic uncertainty (1 sigma) of the mass-weighted normal
#: velocity for each velocimetry source, used in the uncertainty budget.
#: From the velocimetry study on the synthetic presets (docs/velocimetry.md);
#: "wind" and "exit" are user-given speeds whose relation to the gas velocity at
#: the surface is unknown to qogi and are given a wide band.
VELOCITY_SYSTEMATIC = {
    "fluid": 0.10,
    "horn_schunck": 0.25,
    "lucas_kanade": 0.3,
    "farneback": 0.3,
    "dis": 0.3,
    "piv": 0.2,
    "wind": 0.5,
    "exit": 0.5,
}
#: Relative systematic uncertainty (1 sigma) of column densities from the
#: Gaussian line-of-sight model (profile shape; docs/inversion.md), with the
#: gas temperature given or ambient (columns on the ambient lab release with
#: exact truth maps: ~0.99 of the truth).
COLUMN_SYSTEMATIC = 0.05
#: The same with the temperature inferred on the mixing line: on the heated
#: synthetic plumes with exact truth maps (M150 at 90 C, heated methane at
#: 55 C; docs/validation.md) the inverted columns along the surfaces are
#: 0.83-0.90 of the truth: the Gaussian profile of the mean width is smoother
#: than the filaments it stands for, so the fitted mixing line runs hot. The
#: RMS of those deviations, 0.13, is this default.
COLUMN_SYSTEMATIC_INFERRED = 0.13


def _effective_samples(x: np.ndarray) -> float:
    """Effective number of independent samples of a series (integrated
    autocorrelation time, summed until the autocorrelation first drops below
    zero)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 3:
        return float(n)
    d = x - x.mean()
    var = np.dot(d, d) / n
    if var <= 0:
        return float(n)
    tau = 1.0
    for k in range(1, n // 2):
        rho = np.dot(d[:-k], d[k:]) / (n * var)
        if rho <= 0:
            break
        tau += 2 * rho
    return max(1.0, n / tau)


@dataclasses.dataclass(frozen=True)
class Systematics:
    """The run's relative 1-sigma systematics: ``velocity`` (the method's,
    or the config's; at least 1 for a run too short for the velocimetry),
    ``column`` (the column model's with the mixing line's effect added) and
    the mixing line's record for ``info`` (``mixing``; empty without one)."""

    velocity: float
    column: float
    mixing: Dict[str, float]


def finish(st: RunState, complete: bool) -> Result:
    """The Result of the run's blocks analysed (``st.blocks``, in order):
    each surface's and species' per-frame rates, their mean and 90 %
    interval; ``complete`` False for a cancelled run's partial result."""

    rec, cfg, scene, columns, warnings = st.rec, st.cfg, st.scene, st.columns, st.warnings
    outs = st.blocks
    done = sum(o.n for o in outs)
    status_counts: Dict[str, int] = {}
    kept_maps: Dict[int, dict] = {}
    for o in outs:
        for key, v in o.counts.items():
            status_counts[key] = status_counts.get(key, 0) + int(v)
        kept_maps.update(o.maps)
    velocity_info = _block_notes(st)
    systematics = _systematics(st, done)
    results = []
    advice: Dict[str, list] = {sp: [] for sp in cfg.species}
    flux_inputs: Dict[tuple, object] = {}
    # The record of background._choose_background (a dict) or None.
    bg_choice = cast(Optional[dict], velocity_info.get("background_choice"))
    rise_speeds: Dict[int, float] = {}
    self_checks: Dict[str, Dict[str, float]] = {}
    if isinstance(columns, InvertedColumns) and outs:
        columns.prepare_line_shape_curves(range(len(st.surfaces)), cfg.species)
    for j, (s, samples) in enumerate(zip(st.surfaces, st.samples)):
        per_species = {}
        for sp in cfg.species:
            rate, summary, finite, n_eff, measures = _species_rate(
                st, j, s, samples, sp, systematics, bg_choice, done
            )
            if measures is not None and sp == cfg.species[0]:
                self_checks[s.name] = {k: float(v) for k, v in measures.items()}
            if finite.size:
                advice[sp].append(
                    _record_advice(finite, n_eff, summary, samples.dl, columns, j, scene)
                )
            flux_inputs[(j, sp)] = summary
            if sp == cfg.species[0] and summary.mass_line > 0 and finite.size:
                rise_speeds[j] = float(np.sum(finite)) / summary.mass_line * (done / finite.size)
            per_species[sp] = rate
        results.append(SurfaceResult(s, per_species))
    info = {
        "seconds": time.perf_counter() - st.t_start,
        "frames": int(done),
        "frame_rate_hz": float(scene.frame_rate),
        "pixel_m": float(scene.pixel_m),
        "gas_temperature_K": float(scene.gas_K),
        "velocity_systematic": float(systematics.velocity),
        "column_systematic": float(systematics.column),
        **systematics.mixing,
        **velocity_info,
    }
    if self_checks:
        info["self_checks"] = self_checks
    _record_warnings(advice, info, warnings)
    if bg_choice is not None and not cfg.methods.truth_columns:
        for name, held in bg_choice.get("not_gas_free", []):
            warnings.add(
                "background-not-gas-free",
                f"the gas never leaves {100 * held:.0f} % of the surface's pixels: the "
                f"temporal background there is filled from the gas-free neighbours (their "
                f"structure inpainted), uncertain by the background's structure, carried "
                f"in the budget's background term; draw the surface farther downwind or "
                f"give a gas-free background region",
                surface=name,
                held_fraction=held,
            )
    if complete and columns is not None and not cfg.methods.truth_columns:
        check_gas_temperature(
            cfg,
            scene,
            results,
            columns,
            st.samples,
            flux_inputs,
            rise_speeds,
            velocity_info.get("source_xy"),
            warnings,
            info,
        )
    if columns is not None and not cfg.methods.truth_columns:
        _calibrate_intervals(st, results, bg_choice, done, info)
    if not checks.check_result(results, warnings):
        complete = False
    mdc = _min_detectable_columns(st, results) if isinstance(columns, InvertedColumns) else {}
    return Result(
        results,
        config=cfg,
        recording_path=str(rec.path),
        pixel_status=status_counts,
        maps=kept_maps,
        info=info,
        complete=complete,
        warnings=warnings,
        min_detectable_column=mdc,
    )


def _calibrate_intervals(
    st: RunState, results: List[SurfaceResult], bg_choice: Optional[dict], done: int, info: dict
) -> None:
    """Each detected rate's interval calibrated by the error model
    (:mod:`qogi.pipeline.error_model`, fitted on the operating envelope):
    centred where the model expects the truth, its spread beyond the
    budget's in quadrature with the budget's half-widths, never narrower
    than the budget's interval; the model's
    spread becomes the term ``error model``, and the features, expected
    error and the budget's own interval go into ``SpeciesRate.error_model``.
    Rates not detected, not positive or unbounded keep the budget's.
    Every rate also gets its operating point (``SpeciesRate.operating_point``:
    where in the envelope it was measured, the expected error and the
    probability of detection there)."""
    model = error_model.load()
    scene, warnings = st.scene, st.warnings
    method = str((bg_choice or {}).get("method") or st.cfg.background)
    self_codes = set(selfchecks.CODES.values())
    stride = int(info.get("pair_stride") or 1)
    for s in results:
        failed = any(w.code in self_codes and w.surface == s.surface.name for w in warnings)
        for r in s.species.values():
            speed = (r.detection or {}).get("velocity_m_s")
            where = error_model.scene_features(
                speed,
                scene.pixel_m,
                scene.frame_rate,
                done / scene.frame_rate,
                method,
                failed,
                stride,
            )
            if all(math.isfinite(v) for v in r.ci90_kg_h):
                feats = error_model.features(r.mean_kg_h, r.detection_limit_kg_h, r.detected, where)
                if feats is not None:
                    bias, spread = model.expected(feats)
                    r.error_model = model.describe(feats, r.ci90_kg_h)
                    r.ci90_kg_h = error_model.calibrated_interval(
                        r.mean_kg_h, r.ci90_kg_h, bias, spread
                    )
                    r.uncertainty_terms_kg_h["error model"] = abs(r.mean_kg_h) * spread
                    terms = r.uncertainty_terms_kg_h
                    r.dominant_uncertainty = max(terms, key=lambda k: terms[k])
            r.operating_point = _operating_point(model, r, where, scene.distance_m)


def _operating_point(
    model: error_model.ErrorModel, r: SpeciesRate, where: Optional[dict], distance_m: float
) -> dict:
    """Where in the operating envelope ``r`` was measured: the gas-background
    temperature difference, the distance, the gas speed across the surface,
    the signal-to-noise (mean / detection limit), the error the model
    expects there, and the probability of detection at the scene (the rates
    detected with 50 and 90 % probability, and that of a release equal to
    the mean read); None where not stated, with ``pod_note`` saying why."""
    det = r.detection or {}
    gas, bg = det.get("gas_temperature_K"), det.get("background_temperature_K")
    limit = r.detection_limit_kg_h
    speed = det.get("velocity_m_s")
    op: dict = {
        "delta_T_K": None if gas is None or bg is None else float(gas) - float(bg),
        "distance_m": float(distance_m),
        "speed_m_s": None if speed is None else float(speed),
        "snr": (
            float(r.mean_kg_h / limit)
            if limit and limit > 0 and math.isfinite(r.mean_kg_h)
            else None
        ),
        "expected_error": (r.error_model or {}).get("expected_error"),
        "pod_50_kg_h": None,
        "pod_90_kg_h": None,
        "pod_at_mean": None,
        "pod_note": "",
    }
    if where is None or math.isinf(r.ci90_kg_h[1]) or where["flow_range"] > 0:
        # no speed, or one that is not a measurement (speed-not-measured,
        # no-bound-without-speed, a displacement outside the flow's range):
        # what the scene lets one see is not known either
        op["pod_note"] = "not stated: the gas speed across the surface was not measured"
    elif not (limit and limit > 0 and math.isfinite(limit)):
        op["pod_note"] = "not stated: no detection limit"
    elif model.pod is None:
        op["pod_note"] = "not stated: the packaged error model has no probability of detection"
    else:
        op["pod_50_kg_h"] = model.rate_at(0.5, limit, where)
        op["pod_90_kg_h"] = model.rate_at(POD_LEVEL, limit, where)
        if math.isfinite(r.mean_kg_h) and r.mean_kg_h > 0:
            op["pod_at_mean"] = model.probability(r.mean_kg_h, limit, where)
        op["pod_note"] = f"fitted on the {model.provenance.get('fitted_on', 'envelope')}"
    return op


def _min_detectable_columns(st: RunState, results: List[SurfaceResult]) -> Dict[str, np.ndarray]:
    """Per species, the run's minimum-detectable column map [kg/m2]
    (:func:`qogi.pipeline.detection.min_detectable_column`) on the gas-free
    side (10th or 90th percentile) of its frames, the gas at the run's temperature; each
    surface's median of it goes into its detection record."""
    columns = cast(InvertedColumns, st.columns)
    # The gas-free side of the frames' spread: a plume present in most frames
    # (a jet's core) would otherwise read as background with less contrast.
    bg = median_background_K(st.rec, st.frames, percentile=10.0 if st.channel_sign[0] > 0 else 90.0)
    maps = {
        sp: min_detectable_column(
            bg, columns.model, sp, columns.netd_K, st.scene.gas_K, st.scene.ambient_K
        )
        for sp in st.cfg.species
    }
    for res, samples in zip(results, st.samples):
        for sp, rate in res.species.items():
            if rate.detection is not None:
                along = _bilinear(maps[sp], samples.xy)
                finite = along[np.isfinite(along)]
                rate.detection["min_detectable_column_kg_m2"] = (
                    float(np.median(finite)) if finite.size else None
                )
    return maps


def _block_notes(st: RunState) -> Dict[str, object]:
    """The run's notes with those of its longest block (the first of
    equals); with several blocks their count and every flux-level note."""
    outs = st.blocks
    velocity_info = st.info
    if outs:
        longest = outs[int(np.argmax([o.n for o in outs]))]
        velocity_info = {**velocity_info, **longest.velocity_info}
        if len(outs) > 1:
            velocity_info["blocks"] = len(outs)
            notes = sorted(
                {
                    str(o.velocity_info.get("flux_level"))
                    for o in outs
                    if "flux_level" in o.velocity_info
                }
            )
            if len(notes) > 1:
                velocity_info["flux_level"] = "; ".join(notes)
    return velocity_info or {}


def _systematics(st: RunState, done: int) -> Systematics:
    """The run's :class:`Systematics` (``done``: frames with rates)."""

    cfg, columns = st.cfg, st.columns
    vsys = (
        cfg.velocity_systematic
        if cfg.velocity_systematic is not None
        else VELOCITY_SYSTEMATIC[cfg.velocity]
    )
    # Too short a run for the velocimetry: its level is not measured.
    few = not cfg.methods.given_speed and done < checks.MIN_FRAMES_RATE
    if few:
        vsys = max(vsys, 1.0)
    # The inferred temperature's mixing-line slope and its effect on the columns.
    mixing: Dict[str, float] = {}
    col_sys = cfg.column_systematic
    if col_sys is None:
        col_sys = (
            COLUMN_SYSTEMATIC_INFERRED if cfg.conditions.infers_temperature else COLUMN_SYSTEMATIC
        )
    if isinstance(columns, InvertedColumns) and columns.k_K_per_fraction is not None:
        mixing = {
            "mixing_line_K_per_fraction": columns.k_K_per_fraction,
            "mixing_line_sigma_K_per_fraction": columns.k_sigma,
            "mixing_line_pixels": columns.mixing_pixels,
            "mixing_line_column_effect": columns.k_relative_effect,
        }
        col_sys = math.hypot(col_sys, columns.k_relative_effect)
    return Systematics(vsys, col_sys, mixing)


def _species_rate(
    st: RunState, j: int, surface, samples, sp: str, systematics: Systematics, bg_choice, done: int
):
    """Surface ``j``'s rate of species ``sp`` over the run's blocks: its
    :class:`qogi.pipeline.result.SpeciesRate` (mean, 90 % interval, budget terms,
    detection limit), the flux checks' sums, the finite per-frame rates
    [kg/s] and their effective number."""

    rec, scene, columns, warnings = st.rec, st.scene, st.columns, st.warnings
    dl = samples.dl
    parts = [o.flux[j][sp] for o in st.blocks]
    rate = np.concatenate([p.rate for p in parts]) if parts else np.zeros(0)
    pixels = np.concatenate([p.pixels for p in parts]) if parts else np.zeros(0, int)
    mean = float(np.nanmean(rate)) if np.isfinite(rate).any() else float("nan")
    finite = rate[np.isfinite(rate)]
    n_eff = _effective_samples(finite) if finite.size else 0.0
    sd = float(np.std(finite, ddof=1)) if finite.size > 1 else 0.0
    temporal = sd / math.sqrt(n_eff) if n_eff > 0 else 0.0
    col_rand = math.sqrt(sum(p.column_variance for p in parts)) / max(1, finite.size)
    summary = FluxSummary.empty(len(samples.xy))
    for p in parts:
        if p.summary is not None:
            summary += p.summary
    # Relative (multiplicative) terms: the rate is the truth times a factor
    # for each; additive: the record's temporal scatter and the columns' noise.
    relative = {
        "velocity": systematics.velocity,
        "column density": systematics.column,
        "line shape": _line_shape_term(columns, j, sp, summary, warnings, surface.name),
    }
    if bg_choice is not None and not st.cfg.methods.truth_columns:
        relative["background"] = bg_choice["relative"].get(j, 0.0)
    terms = {
        "temporal": temporal * 3600,
        "velocity": abs(mean) * relative["velocity"] * 3600,
        "column density": math.sqrt(col_rand**2 + (abs(mean) * systematics.column) ** 2) * 3600,
        "line shape": abs(mean) * relative["line shape"] * 3600,
    }
    if "background" in relative:
        terms["background"] = abs(mean) * relative["background"] * 3600
    # The self-diagnostics (qogi.pipeline.selfchecks): each measure beyond its
    # threshold warns and adds a relative term sized by the failure.
    measures, failed = _self_checks(st, j, surface.name, sp, summary, relative, warnings)
    if "assumptions" in relative:
        terms["assumptions"] = abs(mean) * relative["assumptions"] * 3600
    mean_h = mean * 3600
    rel = math.sqrt(sum(r * r for r in relative.values()))
    ci = interval90(mean_h, math.hypot(temporal, col_rand) * 3600, rel)
    dominant = max(terms, key=lambda k: terms[k])
    limit, det, v_n = None, None, math.nan
    if isinstance(columns, InvertedColumns):  # not truth columns
        v_n = velocity_from_sums(
            sum(p.cv_sum for p in parts),
            sum(p.c_sum for p in parts),
            np.concatenate([np.zeros(0)] + [p.vabs_median for p in parts]),
        )
    ci = _check_direction(summary, mean, ci, warnings, surface.name, sp, rel)
    if v_n == 0.0 and finite.size:
        ci = _speed_not_measured(st, ci, warnings, surface.name, sp)
    if isinstance(columns, InvertedColumns):
        limit, det = detection_limit_from_sums(
            columns.model,
            sp,
            columns.netd_K,
            columns._bg_t,
            scene.gas_K,
            scene.ambient_K,
            v_n,
            np.concatenate([np.zeros(0)] + [p.width_m for p in parts]),
            dl,
            mean_snr=columns.mean_contrast_snr(j),
        )
        if limit is not None and mean_h < limit:
            why = _speed_unmeasured_reason(st, failed, v_n)
            if why:
                ci = _no_bound_without_speed(ci, limit, v_n, warnings, surface.name, sp, why)
    truth = None
    if rec.truth is not None and sp in rec.truth.emission_rate_kg_s:
        truth = rec.truth.emission_rate_kg_s[sp] * 3600
    times = st.timebase.time_s[:done]
    out = SpeciesRate(
        species=sp,
        time_s=times,
        rate_kg_s=rate,
        mean_kg_h=mean_h,
        ci90_kg_h=ci,
        n_frames=int(finite.size),
        molar_mass_kg_mol=_engine.molar_mass(sp),
        uncertainty_terms_kg_h=terms,
        dominant_uncertainty=dominant,
        pixels_used=pixels,
        truth_kg_h=truth,
        detection_limit_kg_h=limit,
        detection=det,
    )
    return out, summary, finite, n_eff, measures


def _self_checks(st: RunState, j: int, surface: str, sp: str, summary, relative, warnings):
    """Surface j's self-diagnostic measures (:mod:`qogi.pipeline.selfchecks`; None
    without an inversion); for each beyond its threshold a warning and the
    relative term ``relative["assumptions"]``
    (:func:`qogi.pipeline.selfchecks.combined_term`)."""

    columns = st.columns
    if not isinstance(columns, InvertedColumns) or j not in columns.evidence:
        return None, frozenset()
    fluct = [
        float(f)
        for b in st.blocks
        if isinstance(f := b.velocity_info.get("column_fluctuation"), float) and math.isfinite(f)
    ]
    unexplained, in_view, speeds = (
        [
            float(f)
            for b in st.blocks
            if isinstance(f := b.velocity_info.get(key), float) and math.isfinite(f)
        ]
        for key in ("transport_unexplained", "transport_frames_in_view", "transport_speed_m_s")
    )
    plume, plume_contrast = selfchecks.plume_residual(columns.evidence, j)
    ev = dataclasses.replace(
        columns.evidence[j],
        plume_residual=plume,
        plume_contrast=plume_contrast,
        held_error=columns.background.held_error,
        flux_against=summary.flux_against,
        flux_abs=summary.flux_abs,
        upwind_sq=columns.upwind_sums[0],
        upwind_n=int(columns.upwind_sums[1]),
        fluctuation_sum=sum(fluct),
        fluctuation_n=len(fluct),
        unexplained_sum=sum(unexplained),
        unexplained_n=len(unexplained),
        in_view_sum=sum(in_view),
        in_view_n=len(in_view),
        surface_speed_num=summary.speed_num,
        surface_speed_den=summary.speed_den,
        transport_speed_sum=sum(speeds),
        transport_speed_n=len(speeds),
    )
    measures, failed = selfchecks.failure_terms(ev)
    what = {
        "at_bound_fraction": "of the pixel-frames ended on a bound of the inversion (no "
        "column inside the bounds fits their contrast: the background is likely on the "
        "wrong side of the radiance)",
        "negative_fraction": "of the pixel-frames have a contrast of the sign the gas "
        "cannot give (beyond 3 noise): the background is wrong there",
        "background_residual_noise": "noise: the background's error along the surface "
        "(it stands beyond the radiance's own floor where the gas leaves the pixels)",
        "reversed_fraction": "of the flux through the surface runs against its "
        "orientation (the flow reverses)",
        "upwind_contrast_noise": "noise RMS contrast behind the source, where the gas "
        "does not go: the background moves (drifting clouds) or the estimate misses "
        "the scene's structure",
        "plume_residual_noise": "noise: the background's error along another surface "
        "of the run; the velocity, one field along the whole plume, follows the static "
        "pattern it leaves",
        "held_background_error": "of the gas's contrast is the error of the background "
        "where the gas never leaves the pixels (the plume's base, inpainted from the "
        "gas-free pixels around; the inpainting tried on a ring of known pixels there): "
        "the columns of the plume's base are not measured, and the velocity, one field "
        "along the whole plume, follows them",
        "insensitive_fraction": "of the surface's column lies where its background is "
        "so near the gas's temperature that the gas hardly changes the radiance (a pipe as "
        "hot as the gas); it is interpolated from the neighbouring samples",
        "column_fluctuation": "RMS fluctuation of the plume's most fluctuating lines: a "
        "steady, nearly laminar column, whose pattern (instability waves) may travel "
        "slower than its gas, and the flux level follows the pattern",
        "transport_unexplained": "of the plume's column fluctuation is left unexplained by "
        "the flux level's time of flight, more than frames unrelated to each other leave "
        "(the threshold): the displacement it found does not carry the plume's structures, so the "
        "speed is not measured",
        "transport_frames_in_view": "frames is how long the gas stays in view (the frame "
        "beyond the source over the flux level's displacement per frame): its structures "
        "change beyond recognition between frames, and neither the flow nor the time of "
        "flight that sets the flux level follows them, so the speed is not measured",
        "surface_frames_in_view": "frames is how long the gas stays in view at the "
        "surface's own speed, faster than the flux level's time of flight measured (which "
        "then reads the speed low and counts more frames): its structures change beyond "
        "recognition between frames, so the speed is not measured",
        "implied_speed_ratio": "times the speed the flux level's time of flight measured "
        "along the plume is what the surface's own columns would need to carry its rate: "
        "they hold a small part of the gas (a steady core that never leaves its pixels is "
        "taken into the background, or the gas is too fast to see), so the rate there is "
        "not measured",
    }
    for key, term in failed:
        v = measures[key]
        size = f"{v:.1f}" if key.endswith(("_noise", "_in_view", "_ratio")) else f"{100 * v:.0f} %"
        fix = (
            "measure where the plume has turned turbulent (surfaces higher up, a longer "
            "view of the plume)"
            if key == "column_fluctuation"
            else "film the release from where its base is seen against a uniform "
            "background (the gas hides the structure behind it)"
            if key == "held_background_error"
            else "film at a higher frame rate, or from farther away or with a wider view, "
            "so that the gas stays in the frame for more frames"
            if key
            in ("transport_frames_in_view", "transport_unexplained", "surface_frames_in_view")
            else "place the surface farther from the source, where the gas leaves the "
            "pixels between its puffs, or film the release against a uniform background"
            if key == "implied_speed_ratio"
            else "try another background (a gas-free region, or 'percentile') or "
            "surfaces where the background is uniform"
        )
        warnings.add(
            selfchecks.CODES[key],
            f"{size} {what[key]}; threshold {selfchecks.THRESHOLDS[key]:g}"
            f"{' (below)' if key in selfchecks.BELOW else ''}: the rate's "
            f"interval is widened by a relative term of {100 * term:.0f} % (1 sigma); {fix}",
            surface=surface,
            species=sp,
            measure=key,
            value=float(v),
            threshold=float(selfchecks.THRESHOLDS[key]),
            relative_term=float(term),
        )
    if failed:
        relative["assumptions"] = selfchecks.combined_term(failed)
    return measures, frozenset(key for key, _ in failed)


def interval90(mean: float, additive: float, relative: float) -> tuple:
    """The 90 % interval of a rate ``mean`` with ``additive`` (1 sigma, in
    the rate's unit: the record's temporal scatter, the columns' noise) and
    ``relative`` uncertainty (1 sigma, a fraction: velocity, column model,
    line shape, background).

    The relative terms are factors between the truth and the estimate (a
    velocity 10 % slow makes the rate 10 % low whatever the rate), so they
    are log-normal: the truth lies within [m exp(-z s), m exp(z s)] of the
    magnitude m, wider on the far side from zero (a rate read 25 % low
    needs +33 % to reach the truth). The additive part is added to each
    side in quadrature. For small terms this is mean +- z sigma. A relative
    term of 100 % or more says the level is not measured at all (e.g. too
    few frames for the velocimetry): the near side then reaches zero and
    past it by the additive part.
    """
    m = abs(mean)
    up = math.hypot(m * math.expm1(Z90 * relative), Z90 * additive)
    near = m if relative >= 1.0 else -m * math.expm1(-Z90 * relative)
    down = math.hypot(near, Z90 * additive)
    if mean < 0:  # a magnitude read against the surface: mirrored
        up, down = down, up
    return (mean - down, mean + up)


def _line_shape_term(columns, j: int, species: str, summary, warnings, surface: str) -> float:
    """Relative ``line shape`` term of surface j (qogi.pipeline.budget_terms): the largest
    change of the flux when its columns are re-read through the other
    rules; 0 without an inversion (truth columns)."""
    if not isinstance(columns, InvertedColumns):
        return 0.0
    try:
        grid, ratios = columns.line_shape_curves(j, species)
    except (ValueError, RuntimeError, OSError) as e:
        warnings.add(
            "line-shape-term-missing",
            f"the line-shape term could not be sized: {e}",
            surface=surface,
            species=species,
        )
        return 0.0
    return max([abs(f - 1.0) for f in summary.flux_ratios(grid, ratios)], default=0.0)


def _speed_unmeasured_reason(st: RunState, failed, v_n: float) -> str:
    """Why the gas speed a detection limit used is not a measurement ("" when
    it is): a speed self-check failed (``transport-unresolved``), or the
    flow's measured displacement between the frames of its pairs lies below
    its range (:data:`qogi.pipeline.error_model.FLOW_RANGE_PX`: below 1 px
    the pairs' displacement is lost in the noise, and a plume too faint to
    follow reads near zero, its directions cancelling: the envelope's 1 g/h
    at 1.5 m in a 2 m/s wind read 0.02 m/s, 0.6 px per frame). A given
    speed is a measurement of its own."""
    if failed & selfchecks.SPEED_NOT_MEASURED:
        return "transport-unresolved"
    if st.cfg.methods.given_speed or not (math.isfinite(v_n) and v_n > 0):
        return ""
    stride = int(cast(int, _block_notes(st).get("pair_stride")) or 1)
    d = v_n / st.scene.m_s_per_px_frame * stride
    lo = error_model.FLOW_RANGE_PX[0]
    if d < lo:
        return (
            f"the flow read {d:.2g} px between the frames of its pairs, below its {lo:g} px range"
        )
    return ""


def _no_bound_without_speed(
    ci, limit: float, v_n: float, warnings, surface, species, why: str = "transport-unresolved"
):
    """The interval of a rate below its detection limit on a surface whose
    speed the self-checks found not measured (``transport-unresolved``:
    the gas changes beyond recognition between frames, or the time of
    flight does not carry it): the limit assumes the speed the flow read,
    and a plume moving faster would pass unseen, so nothing bounds the
    rate. Its upper end becomes unbounded, with the warning
    ``no-bound-without-speed``. Before this, such a surface said "not
    detected, < X" of truths 2-20x above X (a 1 g/h plume in a 2 m/s wind
    at 1.5 m, 68 px per frame at 15 Hz). The same where the flow's measured
    displacement lies below its range (``why``, :func:`_speed_unmeasured_reason`):
    on the envelope's six seeds, 11 of the 15 such bounds were below their
    truths (1 kg/h read at 0.04 m/s in an 8 m/s wind: "< 0.04 kg/h")."""
    lo = min(float(ci[0]), 0.0)
    warnings.add(
        "no-bound-without-speed",
        f"not detected, and the speed is not measured ({why}): the "
        f"detection limit {limit:.3g} kg/h assumes the {v_n:.3g} m/s the flow read, and "
        f"gas moving faster would pass unseen, so nothing bounds the rate: interval "
        f"[{lo:.4g}, unbounded] kg/h; give the wind speed (velocity 'wind' with "
        f"wind_speed_m_s, --wind-speed), or film so the gas stays in view for more "
        f"frames",
        surface=surface,
        species=species,
        detection_limit_kg_h=float(limit),
        speed_m_s=float(v_n),
    )
    return (lo, math.inf)


def _speed_not_measured(st: RunState, ci, warnings, surface: str, species: str) -> tuple:
    """The interval of a rate whose surface saw no gas speed at all (the
    measured normal speed is zero where gas is and in the frames' medians:
    the flow found no motion, e.g. wind faster than it tracks at the frame
    rate, or gas too faint to follow): the columns may be measured but
    nothing bounds their speed, so nothing bounds the rate. The interval's
    upper end is unbounded (``inf``; ``null`` in the JSON), its lower end at
    most 0 (or where the direction check put it: the magnitude mirrored,
    when the gas may cross the other way), with the warning
    ``speed-not-measured`` saying what would measure it. Before this, such
    a rate read 0 with an interval [0, 0] (or the flux its columns carry at
    a floored speed, ten times below a 1 g/h truth in a 2 m/s wind) and,
    its speed being 0, no detection limit: "0 kg/h" of a plume nobody
    measured."""
    lo = min(float(ci[0]), 0.0)
    scene = st.scene
    warnings.add(
        "speed-not-measured",
        f"no gas speed was measured on the surface (the velocity there is zero in every "
        f"frame: e.g. wind faster than the flow tracks at {scene.frame_rate:g} Hz, where "
        f"1 px per frame is {scene.m_s_per_px_frame:.3g} m/s, or gas too faint to "
        f"follow): the rate is not bounded, interval [{lo:.4g}, unbounded] kg/h; give "
        f"the wind speed (velocity 'wind' with wind_speed_m_s, --wind-speed), record at "
        f"a higher frame rate or from farther away",
        surface=surface,
        species=species,
        metres_per_second_per_px_frame=scene.m_s_per_px_frame,
    )
    return (lo, math.inf)


def _check_direction(
    summary, mean_kg_s: float, ci, warnings, surface: str, species: str, relative: float
) -> tuple:
    """The interval of a rate that runs against the surface's orientation or
    is zero while gas crosses it, widened symmetrically about zero to the
    larger of its own far end and the upper end of the flux the columns
    carry at the floored speed (:func:`~.flux._speed_floor`) with the
    rate's ``relative`` 1-sigma terms (:func:`interval90`;
    docs/pipeline_api.md); with a warning ``flux-against-surface`` or
    ``zero-rate-with-gas``."""
    flag = summary.direction(mean_kg_s)
    if flag is None:
        return ci
    bound = flag["bound_kg_s"] * 3600
    # The direction is what is in doubt, not the magnitude: the interval is
    # the magnitude's either way (mirrored about zero), and at least the
    # flux the columns carry at the floored speed, itself an estimate of
    # the magnitude with the rate's relative terms.
    reach = max(interval90(bound, 0.0, relative)[1], abs(ci[0]), abs(ci[1]))
    lo, hi = min(ci[0], -reach), max(ci[1], reach)
    if flag["reason"] == "zero":
        warnings.add(
            "zero-rate-with-gas",
            f"the rate is zero while gas crosses the surface (no velocity there: e.g. "
            f"a wrong source or flow direction); interval widened to "
            f"[{lo:.4g}, {hi:.4g}] kg/h, the flux its columns carry at the flow's "
            f"speed in either direction",
            surface=surface,
            species=species,
            bound_kg_h=bound,
        )
    else:
        warnings.add(
            "flux-against-surface",
            f"the rate runs against the surface's orientation (away from the source): "
            f"the flux level or the source may be reversed; interval widened to "
            f"[{lo:.4g}, {hi:.4g}] kg/h",
            surface=surface,
            species=species,
            bound_kg_h=bound,
        )
    return (lo, hi)


def _record_advice(finite, n_eff, summary, dl, columns, j, scene) -> dict:
    """qogi.pipeline.budget_terms.record_length_advice for one surface: the mean normal
    speed where gas is, and the plume's width (2.35 sigma of its depth)."""

    sigma = (columns.sigma_m.get(j) if isinstance(columns, InvertedColumns) else None) or float(
        np.sum(dl)
    ) / 4.0
    return record_length_advice(
        finite, scene.frame_rate, n_eff, summary.mean_speed(), 2.3548 * sigma
    )


def _record_warnings(advice: Dict[str, list], info: dict, warnings) -> None:
    """The record length a 10 % mean needs (the longest over the surfaces):
    into ``info["record_length"]`` and, when the record is shorter, the
    warning ``record-too-short``."""
    out = {}
    for sp, all_items in advice.items():
        items = [a for a in all_items if np.isfinite(a["needed_s"])]
        if not items:
            continue
        worst = max(items, key=lambda a: a["needed_s"])
        out[sp] = {k: float(v) for k, v in worst.items()}
        if worst["needed_s"] > worst["record_s"]:
            warnings.add(
                "record-too-short",
                f"a 10 % (1 sigma) mean needs about {worst['needed_s']:.0f} s of record; "
                f"this one is {worst['record_s']:.1f} s (temporal "
                f"{100 * worst['temporal']:.0f} %, flux level "
                f"{100 * worst['level']:.0f} % now)",
                species=sp,
                needed_s=worst["needed_s"],
                record_s=worst["record_s"],
            )
    if out:
        info["record_length"] = out
