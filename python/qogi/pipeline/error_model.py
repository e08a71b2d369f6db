"""The error model: how far a detected rate is from the truth, as measured on
the operating envelope, and the interval calibrated with it (issue 28, item 3).

The budget's interval (:func:`qogi.pipeline.budget.interval90`) is built from
the terms the pipeline can size (temporal scatter, the velocimetry's and the
column model's systematics, the self-checks' failures). On the envelope's
default grid it covered 85 % of the detected rates, and its misses sat where
the scene is hard: a low signal-to-noise, a plume moving too slowly or too
fast for the flow, a short record. The error model carries what the budget
misses, as functions of what the run measures itself (never the truth):

========================= ====================================================
feature                   what
========================= ====================================================
``ln_snr``                ln(mean / detection limit): the measured signal
                          over the noise-equivalent rate at the stated
                          confidence (>= 0 for a detected rate)
``flow_range``            how far the measured gas displacement between the
                          flow's frame pairs lies outside its range, 1-64
                          px: ln(1 / d) below, ln(d / 64) above, 0 inside
                          (d = speed / (pixel x frame rate) x pair stride)
``self_check_failed``     1 when a self-check of the surface failed (its
                          warning was raised)
``percentile_background`` 1 for a temporal-percentile background (the
                          background choice's method or the given one)
``short_record``          ln(3 s / record) when the record is shorter than
                          3 s, else 0
========================= ====================================================

Two linear functions of ``[1, features]`` give the natural log of the ratio
rate / truth expected there (``bias``, fitted as a median) and the spread
beyond the budget's (``ln spread``, fitted as the 90 % quantile of what each
fit row needs to be covered). The model's interval is centred on
``ln(mean) - bias`` with the budget's own half-widths in quadrature with
the spread, each side its own (a near side that reaches zero stays there);
the calibrated interval is the hull of it, the budget's interval and the
mean. The calibration only ever widens: a scene the envelope does not
resemble keeps what its own budget says (a shift alone moved the FAST M150
lab release's covering intervals off its truth), and the rate itself is
never corrected by the model (it is the simulator's).

The coefficients are fitted by ``scripts/fit_error_model.py`` on the
envelope's default grid and stored with their provenance and their
held-out coverage in ``qogi/data/error_model.json``; the model applies only
to detected rates with a positive mean, never to a rate nothing bounds.
It is a simulator's model: its figures hold where the simulator's scenes
resemble the user's (docs/validation/envelope.md, "The error model").

The same fit gives the **probability of detection at the scene** (the
operating point of a result, ``SpeciesRate.operating_point``): how likely a
release of rate ``Q`` is to be reported detected where the run stated the
detection limit ``L``, as a logistic in ``ln(Q / L)`` shifted by the
scene's features (:data:`SCENE_FEATURES`, all but the signal-to-noise),

    ``logit PoD = a ln(Q / L) - (c_0 + c . x)``,

fitted by maximum likelihood on every rate of the envelope with a stated
limit and a measured speed, detected or not. It answers "what would this
scene have detected" from what the run measured: the stated limit carries
the noise, the contrast, the distance and the speed; the shift carries what
the limit's own model leaves out (a plume the flow cannot follow, a
percentile background, a short record). Where the speed was not measured,
nothing is stated. :func:`qogi.pod` is the planning tool (a rendered scene
before one films); this is the record of the scene filmed.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from importlib import resources
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

__all__ = [
    "ErrorModel",
    "FEATURES",
    "POD_LEVEL",
    "SCENE_FEATURES",
    "features",
    "flow_range_excess",
    "scene_features",
    "load",
    "Z90",
]

#: The two-sided 90 % quantile of the standard normal.
Z90 = 1.6448536269514722

#: The features, in the order of the coefficients after the constant.
FEATURES = (
    "ln_snr",
    "flow_range",
    "self_check_failed",
    "percentile_background",
    "short_record",
)
#: The features that describe the scene rather than the rate read in it
#: (the probability of detection's, :meth:`ErrorModel.probability`).
SCENE_FEATURES = FEATURES[1:]

#: The flow's range [px between the frames of a pair] (docs/velocimetry.md):
#: below it the gas's displacement is lost in the noise and the held
#: background, above it the structures change beyond recognition.
FLOW_RANGE_PX = (1.0, 64.0)

#: The probability of detection the scene's headline rate is stated at
#: (OOOOb's periodic screening tiers are stated at 90 %).
POD_LEVEL = 0.90

#: The largest ln spread predicted (a factor e^(1.645 x 3) ~ 140 beyond the
#: budget: no finite interval is much wider than that).
LOG_SPREAD_MAX = 3.0

#: The record length below which ``short_record`` grows [s].
SHORT_RECORD_S = 3.0

FORMAT = "qogi-error-model-1"


def flow_range_excess(displacement_px: float) -> float:
    """How far a displacement between the flow's frame pairs [px] lies
    outside :data:`FLOW_RANGE_PX`: ln(1 / d) below, ln(d / 64) above, 0
    inside (the feature ``flow_range``)."""
    lo, hi = FLOW_RANGE_PX
    d = float(displacement_px)
    return max(0.0, math.log(lo / d)) + max(0.0, math.log(d / hi))


def scene_features(
    speed_m_s: Optional[float],
    pixel_m: float,
    frame_rate_hz: float,
    duration_s: float,
    background: str,
    self_check_failed: bool,
    pair_stride: int = 1,
) -> Optional[Dict[str, float]]:
    """The features of the scene (:data:`SCENE_FEATURES`: every feature but
    the signal-to-noise), whatever the rate read there, or None without a
    measured speed (the flow's range and the detection limit need it)."""
    if speed_m_s is None or not (math.isfinite(speed_m_s) and speed_m_s > 0):
        return None
    d = float(speed_m_s) / (float(pixel_m) * float(frame_rate_hz)) * max(1, int(pair_stride))
    return {
        "flow_range": flow_range_excess(d),
        "self_check_failed": float(bool(self_check_failed)),
        "percentile_background": float(background == "percentile"),
        "short_record": max(0.0, math.log(SHORT_RECORD_S / float(duration_s))),
    }


def features(
    mean_kg_h: float,
    detection_limit_kg_h: Optional[float],
    detected: Optional[bool],
    scene: Optional[Dict[str, float]],
) -> Optional[Dict[str, float]]:
    """The model's features of one rate (the table in the module's
    docstring): its signal-to-noise and the ``scene``'s features
    (:func:`scene_features`); None where the model does not apply: not
    ``detected`` (the result's own decision, :attr:`qogi.SpeciesRate.detected`),
    a mean that is not positive, no measured speed (``scene`` None)."""
    if not (detected and detection_limit_kg_h and mean_kg_h > 0) or scene is None:
        return None
    return {"ln_snr": math.log(mean_kg_h / detection_limit_kg_h), **scene}


def calibrated_interval(
    mean_kg_h: float, ci_budget: Tuple[float, float], bias: float, spread: float
) -> Tuple[float, float]:
    """The hull of the budget's interval ``ci_budget``, the mean, and the
    90 % interval about ``mean / exp(bias)`` with the budget's own
    half-widths (in log space, each side its own) in quadrature with
    ``spread`` (1 sigma of ln(rate / truth)); a budget side that reaches
    zero or beyond is kept as it is."""
    m = float(mean_kg_h)
    lo_b, hi_b = (float(v) for v in ci_budget)
    centre = math.log(m) - bias
    s_up = math.log(hi_b / m) / Z90 if hi_b > m else 0.0
    hi = math.exp(centre + Z90 * math.hypot(s_up, spread)) if math.isfinite(hi_b) else hi_b
    if lo_b <= 0:
        lo = lo_b
    else:
        s_lo = math.log(m / lo_b) / Z90 if lo_b < m else 0.0
        lo = math.exp(centre - Z90 * math.hypot(s_lo, spread))
    return (min(lo, m, lo_b), max(hi, m, hi_b))


@dataclasses.dataclass(frozen=True)
class ErrorModel:
    """Fitted coefficients (``bias`` and ``log_spread``: the constant, then
    one per :data:`FEATURES`) and where they came from (``provenance``:
    grid, seeds, rows, coverage fitted and held out)."""

    bias: Tuple[float, ...]
    log_spread: Tuple[float, ...]
    provenance: dict
    #: The probability of detection's coefficients (module docstring):
    #: ``{"slope": a, "offset": [constant, one per SCENE_FEATURES]}``; None
    #: in a model fitted without it (no probability is then stated).
    pod: Optional[dict] = None

    def __post_init__(self):
        n = len(FEATURES) + 1
        if len(self.bias) != n or len(self.log_spread) != n:
            raise ValueError(
                f"an error model needs {n} coefficients each for the bias and the spread "
                f"(a constant and {', '.join(FEATURES)}); got {len(self.bias)} and "
                f"{len(self.log_spread)}"
            )
        if self.pod is not None and (
            len(self.pod.get("offset", ())) != len(SCENE_FEATURES) + 1
            or not float(self.pod.get("slope", 0.0)) > 0
        ):
            raise ValueError(
                f"an error model's probability of detection needs a positive slope and "
                f"{len(SCENE_FEATURES) + 1} offsets (a constant and "
                f"{', '.join(SCENE_FEATURES)}); got {self.pod}"
            )

    def _x(self, feats: Dict[str, float]) -> np.ndarray:
        return np.array([1.0] + [float(feats[k]) for k in FEATURES])

    def expected(self, feats: Dict[str, float]) -> Tuple[float, float]:
        """``(bias, spread)`` at ``feats``: the expected ln(rate / truth) and
        the spread [1 sigma of it] beyond the budget's."""
        x = self._x(feats)
        return float(x @ np.asarray(self.bias)), float(
            np.exp(np.clip(x @ np.asarray(self.log_spread), -30.0, LOG_SPREAD_MAX))
        )

    def describe(self, feats: Dict[str, float], ci_budget: Sequence[float]) -> dict:
        """What the result records (``SpeciesRate.error_model``): the
        features, the expected error (rate / truth - 1, the median), the
        spread, and the budget's interval before the model."""
        bias, spread = self.expected(feats)
        return {
            "features": {k: float(v) for k, v in feats.items()},
            "expected_error": math.expm1(bias),
            "bias_ln": bias,
            "spread_ln": spread,
            "ci90_budget_kg_h": [float(ci_budget[0]), float(ci_budget[1])],
            "fitted_on": self.provenance.get("fitted_on", ""),
        }

    def _pod_shift(self, scene: Dict[str, float]) -> float:
        assert self.pod is not None
        x = np.array([1.0] + [float(scene[k]) for k in SCENE_FEATURES])
        return float(x @ np.asarray(self.pod["offset"], float))

    def probability(
        self, rate_kg_h: float, limit_kg_h: float, scene: Dict[str, float]
    ) -> Optional[float]:
        """The probability that a release of ``rate_kg_h`` is reported
        detected where the stated detection limit is ``limit_kg_h`` and the
        scene's features are ``scene`` (:func:`scene_features`); None
        without a fitted probability or a positive limit."""
        if self.pod is None or not (limit_kg_h and limit_kg_h > 0):
            return None
        if rate_kg_h <= 0:
            return 0.0
        z = float(self.pod["slope"]) * math.log(rate_kg_h / limit_kg_h) - self._pod_shift(scene)
        return float(0.5 * (1.0 + math.tanh(0.5 * z)))  # the logistic, without overflow

    def rate_at(
        self, probability: float, limit_kg_h: float, scene: Dict[str, float]
    ) -> Optional[float]:
        """The release rate [kg/h] reported detected with ``probability``
        (the inverse of :meth:`probability`)."""
        if self.pod is None or not (limit_kg_h and limit_kg_h > 0):
            return None
        if not 0.0 < probability < 1.0:
            raise ValueError(f"a probability of detection lies in (0, 1); got {probability}")
        logit = math.log(probability / (1.0 - probability))
        ln_ratio = (logit + self._pod_shift(scene)) / float(self.pod["slope"])
        return float(limit_kg_h * math.exp(min(ln_ratio, 700.0)))

    def to_dict(self) -> dict:
        d = {
            "format": FORMAT,
            "features": list(FEATURES),
            "bias": list(self.bias),
            "log_spread": list(self.log_spread),
            "provenance": self.provenance,
        }
        if self.pod is not None:
            d["pod"] = {"slope": float(self.pod["slope"]), "offset": list(self.pod["offset"])}
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ErrorModel:
        if d.get("format") != FORMAT or tuple(d.get("features", ())) != FEATURES:
            raise ValueError(
                f"not a {FORMAT} file with the features {', '.join(FEATURES)} (refit it: "
                f"scripts/fit_error_model.py)"
            )
        pod = d.get("pod")
        return cls(
            tuple(d["bias"]),
            tuple(d["log_spread"]),
            dict(d.get("provenance", {})),
            None if pod is None else {"slope": pod["slope"], "offset": tuple(pod["offset"])},
        )


@functools.lru_cache(maxsize=1)
def load() -> ErrorModel:
    """The packaged model (``qogi/data/error_model.json``)."""
    text = resources.files("qogi").joinpath("data/error_model.json").read_text()
    return ErrorModel.from_dict(json.loads(text))
