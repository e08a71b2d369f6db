"""Probability of detection (PoD): how likely qogi is to report a release of
a given rate as detected, in a given scene (issue 28, item 4).

The PoD is measured, not derived: for a scene (:class:`PodScene`: camera,
distance, gas-background temperature difference, gas speed across the
surface, plume width, record length, camera noise) qogi renders releases of
known rate with the forward model and the camera's seeded NETD noise
(:func:`render_scene`), quantifies each with :func:`qogi.quantify` (the
given speed, every other setting at its default), and counts how often the
result says "detected" (:attr:`qogi.SpeciesRate.detected`: the mean rate at
or above the stated detection limit, :mod:`qogi.pipeline.detection`). A logistic
curve in the log of the rate is fitted to those outcomes
(:func:`fit_logistic`),

    ``PoD(Q) = 1 / (1 + exp(-(ln Q - ln Q50) / s))``,

and the rate detected with 90 % probability is ``Q90 = Q50 exp(s ln 9)``.
Releases of rate zero measure the false-alarm rate. The curve is fitted on
one set of seeds and checked on held-out seeds (``holdout_seeds``): the
observed detection fraction at each rate against the fitted PoD.

The scene is a steady plume crossing a control surface: its column across
the surface a Gaussian of standard deviation ``plume_sigma_m`` (averaged
over each pixel), depth the same, the gas at ambient temperature in front of
a uniform background ``delta_T_K`` colder (emission; negative: absorption),
moving at ``wind_speed_m_s`` across the surface. It does not model a
plume's turbulence or intermittency, the velocimetry (the speed is given),
or a textured background: the PoD is that of the column detection and the
detection decision, an upper bound for a scene whose gas speed must be
measured (docs/detection_limit.md compares it with full plume simulations).

The **minimum-detectable column** per pixel (:func:`min_detectable_column_map`)
is ``(k + z) NEC`` at each pixel's own background temperature: the column a
pixel must hold to be seen in a fraction ``confidence`` of the frames
(:mod:`qogi.pipeline.detection`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from statistics import NormalDist
from typing import Callable, List, Optional, Sequence, Tuple

import numpy as np

from .. import _engine
from ..errors import UsageError
from ..io.recording import Recording, Scene
from ..physics.forward import forward_model
from ..physics.presets import camera_preset
from ..physics.radiometry import radiance_to_temperature
from ..pipeline import QuantifyConfig, quantify
from ..pipeline.detection import (
    CONFIDENCE,
    DETECTION_SIGMA,
    detection_limit_kg_s,
    median_background_K,
    min_detectable_column,
    noise_equivalent_column,
)
from ..pipeline.error_model import POD_LEVEL, flow_range_excess
from ..pipeline.surfaces import Surface
from ..pipeline.velocity import auto_pair_stride

__all__ = [
    "POD_LEVEL",
    "PodScene",
    "PodCurve",
    "Trial",
    "render_scene",
    "trial",
    "fit_logistic",
    "pod",
    "min_detectable_column_map",
    "recording_min_detectable_column",
]

#: Rows of the rendered scene (the surface crosses the middle one).
_ROWS = 16
#: Pixels beyond 5 plume sigmas on each side: gas-free strips for the
#: background beside the surface.
_MARGIN_PX = 12
#: Widest scene rendered [px].
_MAX_WIDTH_PX = 640


@dataclasses.dataclass(frozen=True)
class PodScene:
    """The scene a probability of detection is conditioned on.

    Attributes
    ----------
    camera : str
        A camera preset (:func:`qogi.camera_preset`: ``gf320``, ``fast-m150``).
    distance_m : float
        Camera to plume [m].
    delta_T_K : float
        Gas minus background radiometric temperature [K]: positive, the gas
        seen in emission against a colder background; negative, in
        absorption against a warmer one.
    wind_speed_m_s : float
        Gas speed across the control surface [m/s].
    plume_sigma_m : float
        The plume's standard deviation across the surface [m] (also its
        depth along the line of sight).
    record_s : float
        Record length [s] at the camera's frame rate.
    ambient_temperature_K : float
        Air and gas temperature [K].
    species : str
        The gas.
    netd_K : float or None
        Camera noise [K]; None: the preset's.
    """

    camera: str = "gf320"
    distance_m: float = 2.0
    delta_T_K: float = 5.0
    wind_speed_m_s: float = 1.0
    plume_sigma_m: float = 0.05
    record_s: float = 2.0
    ambient_temperature_K: float = 293.15
    species: str = "CH4"
    netd_K: Optional[float] = None

    def __post_init__(self):
        def need(name, ok, accepted):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and ok(v)):
                raise UsageError(f"PodScene {name} must be {accepted}; got {v!r}")

        need("distance_m", lambda v: 0.1 <= v <= 1e4, "within [0.1, 10000] m")
        need("delta_T_K", lambda v: 0.05 <= abs(v) <= 60, "within +-[0.05, 60] K")
        need("wind_speed_m_s", lambda v: 0.01 <= v <= 50, "within [0.01, 50] m/s")
        need("plume_sigma_m", lambda v: 1e-4 <= v <= 100, "within [0.0001, 100] m")
        need("record_s", lambda v: 0 < v <= 120, "within (0, 120] s")
        need("ambient_temperature_K", lambda v: 220 <= v <= 330, "within [220, 330] K")
        if self.netd_K is not None:
            need("netd_K", lambda v: 1e-3 <= v <= 1.0, "within [0.001, 1] K or None")

        try:
            camera_preset(self.camera)
        except (KeyError, ValueError) as e:
            raise UsageError(f"PodScene camera: {e}") from None
        try:
            _engine.molar_mass(self.species)
        except ValueError as e:
            raise UsageError(f"PodScene species: {e}") from None

    @property
    def background_K(self) -> float:
        """The background's radiometric temperature [K]."""
        return self.ambient_temperature_K - self.delta_T_K

    @property
    def flow_displacement_px(self) -> float:
        """The gas's displacement between the two frames of a flow pair
        [px]: its speed over the pixel and frame rate, times the pair stride
        the pipeline would choose (:func:`qogi.pipeline.velocity.auto_pair_stride`)."""
        fps = camera_preset(self.camera).frame_rate_hz
        if fps is None:  # a camera without a frame rate: unknown
            return math.nan
        d = self.wind_speed_m_s / (_pixel_m(self) * fps)
        return d * auto_pair_stride(d)

    @property
    def speed_measurable(self) -> bool:
        """Whether that displacement lies in the flow's range (1-64 px,
        :data:`qogi.pipeline.error_model.FLOW_RANGE_PX`). Outside it the
        pipeline's flow is not expected to measure the speed (the envelope's
        1 g/h at 1.5 m in a 2 m/s wind, 68 px per frame: no speed, no
        decision), and the PoD, measured with the speed given, is an upper
        bound."""
        d = self.flow_displacement_px
        return not math.isfinite(d) or flow_range_excess(d) == 0.0

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def _camera(scene: PodScene, width: int):

    cam = camera_preset(scene.camera)
    netd = cam.netd_K if scene.netd_K is None else float(scene.netd_K)
    return dataclasses.replace(cam, width=width, height=_ROWS, netd_K=netd)


def _model(scene: PodScene):

    return forward_model(camera_preset(scene.camera).channels, [scene.species])


def _pixel_m(scene: PodScene) -> float:

    return scene.distance_m * camera_preset(scene.camera).ifov_rad


def _width_px(scene: PodScene) -> int:
    sigma_px = scene.plume_sigma_m / _pixel_m(scene)
    w = int(math.ceil(10.0 * sigma_px)) + 2 * _MARGIN_PX + 1
    if w > _MAX_WIDTH_PX:
        raise UsageError(
            f"the plume (sigma {scene.plume_sigma_m:g} m) spans {w} pixels at "
            f"{scene.distance_m:g} m (at most {_MAX_WIDTH_PX}): give a narrower "
            "plume_sigma_m or a larger distance_m"
        )
    return w


def stated_limit_kg_h(scene: PodScene, confidence: float = CONFIDENCE) -> float:
    """The detection limit :mod:`qogi.pipeline.detection` states for the scene [kg/h]:
    ``(k + z) NEC v w`` with ``w = sqrt(2 pi) sigma`` (the Gaussian's
    effective width) widened by the pixel (``sqrt(w^2 + p^2)``)."""
    model = _model(scene)
    netd = scene.netd_K
    if netd is None:
        netd = camera_preset(scene.camera).netd_K
    amb = scene.ambient_temperature_K
    nec = noise_equivalent_column(model, scene.species, netd, scene.background_K, amb, amb)
    w = math.hypot(math.sqrt(2 * math.pi) * scene.plume_sigma_m, _pixel_m(scene))
    return detection_limit_kg_s(nec, scene.wind_speed_m_s, w, confidence) * 3600.0


def render_scene(scene: PodScene, rate_kg_h: float, seed: int):
    """A recording of a steady release of ``rate_kg_h`` [kg/h] in ``scene``
    (module docstring), the control surface across it, and the true rate
    through that surface [kg/h] (the rate less the Gaussian's tails beyond
    the surface's ends, a part in 1e6).

    Returns
    -------
    (qogi.Recording, qogi.Surface, float)
    """

    if not (math.isfinite(rate_kg_h) and rate_kg_h >= 0):
        raise UsageError(f"rate must be a finite number >= 0 kg/h; got {rate_kg_h!r}")
    width = _width_px(scene)
    cam = _camera(scene, width)
    model = _model(scene)
    p = _pixel_m(scene)
    sigma, v, amb = scene.plume_sigma_m, scene.wind_speed_m_s, scene.ambient_temperature_K
    # Column density per pixel [kg/m2]: the Gaussian's mass across each pixel
    # (kg per metre of plume along the flow) / the pixel's width, such that
    # sum c p v = Q.
    edges = (np.arange(width + 1) - width / 2.0) * p / sigma
    cdf = np.array([NormalDist().cdf(e) for e in edges])
    q = rate_kg_h / 3600.0
    col = q / v * np.diff(cdf) / p
    per_fraction = float(
        np.asarray(model.column_density([[1.0]], amb, sigma, amb)[scene.species]).reshape(-1)[0]
    )
    frac = col / per_fraction
    if frac.max() > 0.5:
        raise UsageError(
            f"{rate_kg_h:g} kg/h in a plume of sigma {scene.plume_sigma_m:g} m at "
            f"{v:g} m/s is a peak volume fraction of {frac.max():.2g} (at most 0.5): "
            "a rate this high is far above any detection limit; give lower rates"
        )
    t_img = _clean_image(scene, tuple(float(f) for f in frac))
    n = max(2, int(round(scene.record_s * cam.frame_rate_hz)))
    rng = np.random.default_rng(seed)
    c = len(cam.channels)
    frames = np.broadcast_to(t_img[None], (n, c, _ROWS, width)) + rng.normal(
        0.0, cam.netd_K, (n, c, _ROWS, width)
    )
    rec = Recording.from_arrays(
        frames.astype(np.float32),
        quantity="radiometric_temperature",
        camera=cam,
        scene=Scene(
            distance_m=scene.distance_m,
            ambient_temperature_K=amb,
            pressure_Pa=101325.0,
            species=(scene.species,),
        ),
    )
    y = _ROWS // 2
    a, b = 2, width - 3
    surface = Surface([(a, y), (b, y)], name="S")
    inside = slice(a, b + 1)
    truth = float(col[inside].sum() * p * v * 3600.0)
    return rec, surface, truth


@functools.lru_cache(maxsize=32)
def _clean_image(scene: PodScene, fractions: Tuple[float, ...]) -> np.ndarray:
    """The noise-free radiometric temperature (C, 1, W) of a row of peak
    fractions (one band radiance per rate: the seeds share it)."""

    model = _model(scene)
    amb = scene.ambient_temperature_K
    x = np.asarray(fractions, float)[:, None]
    L = model.band_radiance(x, amb, scene.plume_sigma_m, amb, scene.background_K)  # (W, C)
    return radiance_to_temperature(np.asarray(L).T[None, :, None, :], model.channels)[0]


@dataclasses.dataclass(frozen=True)
class Trial:
    """One release quantified: its rate [kg/h], the seed, whether qogi said
    "detected", the mean rate read and the limit stated [kg/h]."""

    rate_kg_h: float
    seed: int
    detected: bool
    mean_kg_h: float
    limit_kg_h: Optional[float]


def trial(scene: PodScene, rate_kg_h: float, seed: int) -> Trial:
    """Render one release (:func:`render_scene`) and quantify it with the
    scene's speed given and every other setting at its default."""

    rec, surface, _ = render_scene(scene, rate_kg_h, seed)
    cfg = QuantifyConfig(
        species=[scene.species],
        velocity="wind",
        wind_speed_m_s=scene.wind_speed_m_s,
        num_threads=1,
    )
    r = quantify(rec, [surface], cfg).total(scene.species)
    return Trial(
        float(rate_kg_h), int(seed), bool(r.detected), float(r.mean_kg_h), r.detection_limit_kg_h
    )


#: Ridge on the logistic's steepness b = 1/s [1/ln(rate)^2 ... per trial's
#: log-likelihood]: keeps the fit finite where the outcomes separate
#: perfectly between two rates, and hardly moves it where some rate has a
#: partial detection fraction.
_RIDGE = 1e-3


def fit_logistic(rates_kg_h: Sequence[float], detected: Sequence[bool]) -> Tuple[float, float]:
    """Maximum-likelihood logistic curve in the log of the rate,
    ``PoD = 1 / (1 + exp(-(ln Q - ln Q50) / s))``: returns ``(Q50, s)``
    [kg/h, -].

    Rates of zero (false-alarm trials) are left out. A small ridge on the
    steepness ``1/s`` keeps the fit finite where the outcomes separate
    perfectly (every trial below some rate missed, every one above it
    detected). (Pseudo-counts at every rate, the empirical logit's
    correction, were tried first: at the rates far from the transition they
    pulled the curve 20-35 points shallower than the held-out outcomes.)
    """
    q = np.asarray(rates_kg_h, float)
    d = np.asarray(detected, bool)
    keep = q > 0
    q, d = q[keep], d[keep]
    levels = np.unique(q)
    if levels.size < 2:
        raise ValueError("fit_logistic needs outcomes at two or more rates > 0")
    x = np.log(levels)
    n = np.array([np.sum(q == lv) for lv in levels], float)
    k = np.array([np.sum(d[q == lv]) for lv in levels], float)
    # Newton's method on (a, b) of logit p = a + b (x - x0), maximising the
    # log-likelihood less ridge * N * b^2 / 2.
    x0 = float(np.average(x, weights=n))
    xc = x - x0
    lam = _RIDGE * float(n.sum())
    a, b = 0.0, 1.0
    for _ in range(200):
        p = 1.0 / (1.0 + np.exp(-(a + b * xc)))
        g = np.array([np.sum(k - n * p), np.sum((k - n * p) * xc) - lam * b])
        w = n * p * (1 - p)
        h = np.array([[w.sum(), (w * xc).sum()], [(w * xc).sum(), (w * xc * xc).sum() + lam]])
        step = np.linalg.solve(h + 1e-12 * np.eye(2), g)
        shrink = min(1.0, 5.0 / max(1e-12, float(np.max(np.abs(step)))))  # damped far away
        a, b = a + shrink * step[0], b + shrink * step[1]
        if np.max(np.abs(step)) < 1e-10:
            break
    if not b > 0:
        raise ValueError(
            "the detections do not grow with the rate (fitted slope "
            f"{b:.3g}): widen the range of rates or add seeds"
        )
    return float(math.exp(x0 - a / b)), float(1.0 / b)


@dataclasses.dataclass
class PodCurve:
    """A scene's probability of detection (:func:`pod`).

    Attributes
    ----------
    scene : PodScene
    q50_kg_h, slope : float
        The fitted logistic (:func:`fit_logistic`).
    trials : list of Trial
        The outcomes the fit used.
    holdout : list of Trial
        Outcomes on held-out seeds (the check).
    false_alarm : float or None
        Fraction of the rate-zero trials said "detected".
    stated_limit_kg_h : float
        The limit qogi.pipeline.detection states for this scene.
    """

    scene: PodScene
    q50_kg_h: float
    slope: float
    trials: List[Trial]
    holdout: List[Trial]
    false_alarm: Optional[float]
    stated_limit_kg_h: float

    def probability(self, rate_kg_h):
        """The fitted PoD at ``rate_kg_h`` [kg/h] (scalar or array; 0 at 0)."""
        q = np.asarray(rate_kg_h, float)
        with np.errstate(divide="ignore"):
            z = (np.log(np.where(q > 0, q, np.nan)) - math.log(self.q50_kg_h)) / self.slope
        out = np.where(q > 0, 1.0 / (1.0 + np.exp(-np.nan_to_num(z, nan=-np.inf))), 0.0)
        return float(out) if out.ndim == 0 else out

    def rate_at(self, probability: float = POD_LEVEL) -> float:
        """The rate [kg/h] detected with ``probability`` (0 < p < 1)."""
        if not 0 < probability < 1:
            raise ValueError(f"probability must be within (0, 1); got {probability}")
        return self.q50_kg_h * math.exp(self.slope * math.log(probability / (1 - probability)))

    def table(self, which: str = "holdout") -> List[dict]:
        """Per rate: trials, the observed detection fraction and the fitted
        PoD, for the ``"fit"`` trials or the ``"holdout"`` ones."""
        ts = self.holdout if which == "holdout" else self.trials
        rows = []
        for q in sorted({t.rate_kg_h for t in ts}):
            at = [t for t in ts if t.rate_kg_h == q]
            rows.append(
                dict(
                    rate_kg_h=q,
                    n=len(at),
                    observed=float(np.mean([t.detected for t in at])),
                    fitted=self.probability(q),
                )
            )
        return rows

    def to_dict(self) -> dict:
        return {
            "scene": self.scene.to_dict(),
            "q50_kg_h": self.q50_kg_h,
            "slope": self.slope,
            f"rate_pod{int(round(100 * POD_LEVEL))}_kg_h": self.rate_at(POD_LEVEL),
            "false_alarm": self.false_alarm,
            "stated_limit_kg_h": self.stated_limit_kg_h,
            "flow_displacement_px": _finite(self.scene.flow_displacement_px),
            "speed_measurable": self.scene.speed_measurable,
            "upper_bound": not self.scene.speed_measurable,
            "fit": self.table("fit"),
            "holdout": self.table("holdout"),
        }


def _finite(x: float) -> Optional[float]:
    return float(x) if math.isfinite(x) else None


def default_rates(scene: PodScene) -> List[float]:
    """Rates [kg/h] the PoD is measured at: zero (false alarms) and the
    stated limit times 2^(-1/2) ... 2^2 in steps of sqrt(2) (where the curve
    rises: on the steady scenes measured, from about 1x to 2x the stated
    limit; steps of 2 left no rate with a partial detection fraction)."""
    lim = stated_limit_kg_h(scene)
    return [0.0] + [lim * 2.0 ** (k / 2) for k in range(-1, 5)]


def pod(
    scene: PodScene,
    rates_kg_h: Optional[Sequence[float]] = None,
    seeds: Sequence[int] = tuple(range(6)),
    holdout_seeds: Sequence[int] = tuple(range(100, 106)),
    progress: Optional[Callable[[float, str], object]] = None,
    refine: bool = True,
) -> PodCurve:
    """The probability of detection of ``scene`` (module docstring).

    Parameters
    ----------
    scene : PodScene
    rates_kg_h : sequence of float, optional
        Release rates [kg/h] (include 0 for the false-alarm rate); default
        :func:`default_rates`.
    seeds, holdout_seeds : sequence of int
        Noise seeds of the trials the curve is fitted on, and of those it is
        checked on (may be empty).
    progress : callable(fraction, message), optional
        Called after each trial.
    refine : bool
        Where no rate of the fit's trials has a partial detection fraction
        (the detection switches between two neighbouring rates on every
        seed: on a steady plume the mean rate of a record hardly varies),
        add two rates between those two, geometrically spaced, so that the
        curve's steepness is measured rather than set by the fit's
        smoothing; the held-out seeds run at them too.

    Returns
    -------
    PodCurve
    """
    rates = list(default_rates(scene) if rates_kg_h is None else rates_kg_h)
    if not rates or any(not (math.isfinite(q) and q >= 0) for q in rates):
        raise UsageError(f"rates must be finite numbers >= 0 kg/h; got {rates}")
    seeds, holdout_seeds = list(seeds), list(holdout_seeds)
    if len(seeds) < 1:
        raise UsageError("pod needs at least one seed to fit on")
    # The trials planned: every rate on every seed, and two refining rates.
    total = (len(rates) + (2 if refine else 0)) * (len(seeds) + len(holdout_seeds))
    done = [0]

    def run(qs, ss) -> List[Trial]:
        out = []
        for s in ss:
            for q in qs:
                out.append(trial(scene, q, s))
                done[0] += 1
                if progress is not None:
                    progress(min(1.0, done[0] / total), f"{q * 1e3:.3g} g/h, seed {s}")
        return out

    fit = run(rates, seeds)
    if refine:
        extra = _refining_rates(fit)
        fit += run(extra, seeds)
        rates += extra
    held = run(rates, holdout_seeds)
    zero = [t.detected for t in fit + held if t.rate_kg_h == 0]
    q50, slope = fit_logistic([t.rate_kg_h for t in fit], [t.detected for t in fit])
    return PodCurve(
        scene=scene,
        q50_kg_h=q50,
        slope=slope,
        trials=fit,
        holdout=held,
        false_alarm=float(np.mean(zero)) if zero else None,
        stated_limit_kg_h=stated_limit_kg_h(scene),
    )


def _refining_rates(trials: Sequence[Trial]) -> List[float]:
    """Two rates between the highest rate never detected and the next
    higher rate, when no rate was detected on some seeds only (else none)."""
    levels = sorted({t.rate_kg_h for t in trials if t.rate_kg_h > 0})
    frac = {q: np.mean([t.detected for t in trials if t.rate_kg_h == q]) for q in levels}
    if any(0 < f < 1 for f in frac.values()):
        return []
    for lo, hi in zip(levels, levels[1:]):
        if frac[lo] == 0 and frac[hi] == 1:
            return [lo * (hi / lo) ** (i / 3) for i in (1, 2)]
    return []


def min_detectable_column_map(
    background_K: np.ndarray,
    camera,
    gas_K: float,
    ambient_K: float,
    species: str = "CH4",
    netd_K: Optional[float] = None,
    confidence: float = CONFIDENCE,
    detection_sigma: float = DETECTION_SIGMA,
) -> np.ndarray:
    """Per pixel, the column density [kg/m2] a pixel must hold to be seen in
    a fraction ``confidence`` of the frames: ``(k + z) NEC(T_bg)`` with
    ``NEC`` the noise-equivalent column at that pixel's background
    radiometric temperature (:func:`qogi.pipeline.detection.noise_equivalent_column`).

    The other parameters and the result are those of
    :func:`qogi.pipeline.detection.min_detectable_column` (``background_K``
    finite, (H, W), e.g. a gas-free frame or a temporal median of the first
    channel); this builds the camera's forward model for ``species`` and
    takes its NETD.

    Parameters
    ----------
    camera : qogi.Camera or str
        The camera (or a preset name): its channels and NETD.
    netd_K : float, optional
        Camera noise [K]; None: the camera's.
    """

    cam = camera_preset(camera) if isinstance(camera, str) else camera
    bg = np.asarray(background_K, float)
    if bg.ndim != 2 or not np.all(np.isfinite(bg)):
        raise ValueError(
            f"background_K must be a finite (H, W) image in K; got shape {bg.shape}"
            + ("" if np.all(np.isfinite(bg)) else " with non-finite pixels")
        )
    netd = cam.netd_K if netd_K is None else netd_K
    if netd is None:
        raise ValueError("the camera has no NETD: give netd_K")
    model = forward_model(cam.channels, [species])
    return min_detectable_column(
        bg, model, species, netd, gas_K, ambient_K, confidence, detection_sigma
    )


def recording_min_detectable_column(
    recording, species: Optional[str] = None, gas_K: Optional[float] = None, max_frames: int = 50
) -> Tuple[np.ndarray, np.ndarray]:
    """The minimum-detectable column map [kg/m2] of a recording and the
    background it was computed on [K] (each (H, W)).

    The background is the per-pixel temporal median of the first channel's
    radiometric temperature over up to ``max_frames`` frames spread over the
    record (where the gas comes and goes, the gas-free value); the gas is at
    ``gas_K`` (default the recording's ambient temperature, as the run's
    default ``gas_temperature="ambient"``); ``species`` defaults to the
    recording's first, else CH4. See :func:`min_detectable_column_map`.
    """
    bg = median_background_K(recording, max_frames=max_frames)
    sc = recording.scene
    sp = species or (sc.species[0] if sc.species else "CH4")
    amb = sc.ambient_temperature_K
    gas = amb if gas_K is None else gas_K
    return min_detectable_column_map(bg, recording.camera, gas, amb, species=sp), bg
