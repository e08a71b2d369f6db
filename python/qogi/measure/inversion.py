"""Per-pixel inversion: Gaussian-plume parameters, column densities and their
uncertainties from measured band radiances.

Each pixel's measured contrast ``y_c = L_c - L_bg,c`` in every channel c is
matched, in the least-squares sense, by the forward model's contrast of a
Gaussian plume (thesis eqs. 4-6, :mod:`qogi.physics.forward`) with peak volume
fractions ``x_i``, peak temperature ``T_peak`` and depth ``sigma``. The
residuals are normalised by each channel's radiance noise

    n_c = NETD_c x dL_c/dT (T_bg,c)

(optionally widened by a relative model error), and a Gaussian prior on any
parameter adds ``(theta - mean) / prior_sigma``. The column density of
species i (eq. 6) and its path concentration follow from the solution:

    c_i = (M_i / N_A) integral x_i(s) p / (k_B T(s)) ds   [kg/m2],
    ppm m_i = 1e6 integral x_i(s) ds = 1e6 sqrt(2 pi) x_i sigma,

with 1-sigma uncertainties from the solver's covariance ``(J^T J)^-1``
(noise-normalised residuals) propagated through their Jacobians.

Each parameter is fixed, free within bounds, or free with a prior
(:func:`fixed`, :func:`free`, :func:`prior`). Typical set-ups:

* single channel (a GF320): one species free, ``temperature="ambient"`` (or
  the known gas temperature), ``sigma_m`` given or from the plume width
  (:func:`plume_depth_from_width`); solved by a bracketed Newton iteration;
* multichannel (the fast-m150): the species free, ``temperature=free()``;
  ``sigma`` fixed or with a prior. A free sigma is nearly degenerate with the
  fractions (without self-broadening the radiance depends on ``x_i`` and
  ``sigma`` only through ``x_i sigma``); the column density stays well
  determined either way, and ``condition_number`` reports the degeneracy.

The fast path evaluates a per-scene table of the fast forward model (built
once per ambient temperature in seconds, cached; its error against the binned
model is printed by ``benchmarks/bench_inversion.py``) and solves with Ceres'
TinySolver; spectrally overlapping species fall back to ``ceres::Solve`` on
the full binned model. See ``docs/inversion.md``.

Every pixel gets a status: ``converged``, ``at_bound`` (a parameter held on
a bound; ``bound_mask`` says which), ``below_detection`` (|y_c| < k n_c in
every channel, decided before solving), ``failed`` (non-finite input, a
background outside the tables, or no convergence), or ``masked`` (not
selected). Outputs are never NaN; :meth:`InversionResult.masked` gives masked
arrays of the usable pixels.
"""

from __future__ import annotations

import copy
import math
import threading
from dataclasses import dataclass, field
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from .. import _engine
from ..physics.forward import ForwardModel

__all__ = [
    "Parameter",
    "fixed",
    "free",
    "prior",
    "tied",
    "Inversion",
    "InversionResult",
    "scene_table",
    "invert_on_mixing_line",
    "MixingLineSlope",
    "mixing_line_slope",
    "mixing_line_slope_sample",
    "mixing_line_slope_from_profile",
    "plume_depth_from_width",
    "STATUS_NAMES",
    "CONVERGED",
    "AT_BOUND",
    "BELOW_DETECTION",
    "FAILED",
    "MASKED",
    "AMBIGUOUS",
]

CONVERGED, AT_BOUND, BELOW_DETECTION, FAILED, MASKED = 0, 1, 2, 3, 4
#: Flag bit: a second, distinct solution fits within chi2 + 4 of the reported
#: one; the uncertainties include the spread between the two.
AMBIGUOUS = 1
#: Status names by code.
STATUS_NAMES = ("converged", "at_bound", "below_detection", "failed", "masked")

#: Default bounds of a free peak temperature relative to ambient [K].
DEFAULT_TEMPERATURE_SPAN_K = (-10.0, 100.0)


# ---------------------------------------------------------------------------
# Parameter specifications


@dataclass(frozen=True)
class Parameter:
    """How one parameter is treated.

    Attributes
    ----------
    mode : {"fixed", "free", "prior", "tied"}
    value : float or None
        Fixed value, prior mean, start value of a free parameter, or the
        ratio of a tied fraction.
    prior_sigma : float or None
        1-sigma width of a Gaussian prior (mode "prior").
    lower, upper : float or None
        Bounds of an estimated parameter (None: the default bounds).
    tied_to : str or None
        For a tied fraction: the species it follows.
    """

    mode: str
    value: Optional[float] = None
    prior_sigma: Optional[float] = None
    lower: Optional[float] = None
    upper: Optional[float] = None
    tied_to: Optional[str] = None


def fixed(value: float) -> Parameter:
    """A parameter held at ``value``."""
    return Parameter("fixed", float(value))


def free(
    lower: Optional[float] = None, upper: Optional[float] = None, start: Optional[float] = None
) -> Parameter:
    """An estimated parameter within ``[lower, upper]`` (default bounds when None)."""
    return Parameter(
        "free",
        None if start is None else float(start),
        None,
        None if lower is None else float(lower),
        None if upper is None else float(upper),
    )


def prior(
    mean: float, sigma: float, lower: Optional[float] = None, upper: Optional[float] = None
) -> Parameter:
    """An estimated parameter with a Gaussian prior N(mean, sigma^2)."""
    if not (np.isfinite(sigma) and sigma > 0):
        raise ValueError(f"prior sigma must be finite and > 0; got {sigma}")
    return Parameter(
        "prior",
        float(mean),
        float(sigma),
        None if lower is None else float(lower),
        None if upper is None else float(upper),
    )


def tied(species: str, ratio: float) -> Parameter:
    """A fraction following another species': ``x = ratio x_species`` (a
    known composition; e.g. ``tied("CH4", 1.0)`` for CO2 in a 50/50 mix).
    With the composition known, the ratio of different bands' contrasts
    measures the gas temperature (Planck's law differs between bands)."""
    if not (np.isfinite(ratio) and ratio > 0):
        raise ValueError(f"tied ratio must be finite and > 0; got {ratio}")
    return Parameter("tied", float(ratio), tied_to=str(species))


def _as_parameter(p, name: str) -> Parameter:
    if isinstance(p, Parameter):
        if p.mode not in ("fixed", "free", "prior", "tied"):
            raise ValueError(
                f"{name}: mode must be 'fixed', 'free', 'prior' or 'tied'; got {p.mode!r}"
            )
        return p
    if isinstance(p, str):
        if p == "free":
            return free()
        raise ValueError(
            f"{name}: expected a number, 'free', or qogi.inversion.fixed/free/prior(...); got {p!r}"
        )
    try:
        return fixed(float(p))
    except (TypeError, ValueError):
        raise ValueError(
            f"{name}: expected a number, 'free', or qogi.inversion.fixed/free/prior(...); got {p!r}"
        ) from None


_MODES = {
    "fixed": _engine.ParameterMode.fixed,
    "free": _engine.ParameterMode.free,
    "prior": _engine.ParameterMode.prior,
    "tied": _engine.ParameterMode.tied,
}


def _spec(
    p: Parameter,
    default_value: float,
    default_bounds: Tuple[float, float],
    species: Optional[Sequence[str]] = None,
):
    if p.mode == "tied":
        if species is None:
            raise ValueError("only fractions can be tied")
        if p.tied_to is None or p.value is None:
            raise ValueError(
                "a tied fraction needs tied_to (the species) and value (the ratio): "
                "use qogi.inversion.tied(species, ratio)"
            )
        if p.tied_to not in species:
            raise ValueError(
                f"tied to {p.tied_to!r}, which is not one of the species {list(species)}"
            )
        return _engine.ParameterSpec(
            _MODES["tied"], p.value, 0.0, 0.0, 0.0, list(species).index(p.tied_to)
        )
    lo = default_bounds[0] if p.lower is None else p.lower
    hi = default_bounds[1] if p.upper is None else p.upper
    value = default_value if p.value is None else p.value
    if p.mode == "fixed":
        return _engine.ParameterSpec(_MODES["fixed"], value, 0.0, 0.0, 0.0)
    return _engine.ParameterSpec(_MODES[p.mode], value, p.prior_sigma or 0.0, lo, hi)


# ---------------------------------------------------------------------------
# Scene tables (cached per model and scene)

_tables: Dict[tuple, Tuple[object, _engine.SceneTable]] = {}  # key -> (fast model, table)
_tables_lock = threading.Lock()


def scene_table(
    model: ForwardModel,
    ambient_temperature_K: float,
    *,
    min_peak_temperature_K: float,
    max_peak_temperature_K: float,
    max_sigma_m: float = 2.0,
    progress=None,
    **options,
):
    """The per-scene table of ``model``'s fast forward model, built once and
    cached for this process.

    Parameters
    ----------
    model : ForwardModel
    ambient_temperature_K : float, K
        T_amb of the scene (edges of the plume).
    min_peak_temperature_K, max_peak_temperature_K : float, K
        Range of peak temperatures the inversion may use.
    max_sigma_m : float, m, default 2
        Largest plume depth sigma (the table covers x sigma <= it).
    options
        Further :class:`qogi._engine.SceneTableOptions` fields
        (``temperature_step_K=5``, ``nodes_per_decade=8``, ``fraction_nodes=4``,
        ``thin_optical_depth=1e-5``, ``min_background_K=150``,
        ``max_background_K=700``, ``planck_tolerance=1e-8``, ``num_nodes=0``,
        ``linear_optical_depth=1e-4``,
        ``num_threads=0``).

    Returns
    -------
    qogi._engine.SceneTable, or None when the species overlap spectrally
    (then only the full binned model can be inverted).
    """
    fast = model.fast
    if _engine.spectral_overlaps(fast):
        return None
    opts = _engine.SceneTableOptions(
        ambient_temperature_K=float(ambient_temperature_K),
        min_peak_temperature_K=float(min_peak_temperature_K),
        max_peak_temperature_K=float(max_peak_temperature_K),
        max_sigma_m=float(max_sigma_m),
        **options,
    )
    key = (id(fast), tuple(sorted(opts.to_dict().items())))
    with _tables_lock:
        hit = _tables.get(key)
    if hit is not None and hit[0] is fast:
        return hit[1]
    table = _engine.SceneTable(fast, opts, progress)
    with _tables_lock:
        if len(_tables) >= 8:
            _tables.pop(next(iter(_tables)))
        _tables[key] = (fast, table)
    return table


# ---------------------------------------------------------------------------
# Results


@dataclass
class InversionResult:
    """Per-pixel results; arrays have the input's pixel shape (with a leading
    frame axis for :meth:`Inversion.invert_frames`).

    Fill values (never NaN): ``below_detection`` pixels have fractions 0,
    column densities 0 and ``column_density_sigma`` the 1-sigma
    noise-equivalent column (optically thin, all channels); ``failed`` and
    ``masked`` pixels have zeros. Use :attr:`valid` or :meth:`masked`.
    """

    species: list
    status: np.ndarray
    bound_mask: np.ndarray  # bit p: parameter p held on a bound
    flags: np.ndarray  # bit 0: AMBIGUOUS
    parameter_names: list
    parameters: np.ndarray  # (..., P): fractions, T_peak [K], sigma [m]
    parameter_sigma: np.ndarray  # (..., P)
    covariance: np.ndarray  # (..., P, P)
    column_density: Dict[str, np.ndarray]  # kg/m2
    column_density_sigma: Dict[str, np.ndarray]  # kg/m2
    path_concentration_ppm_m: Dict[str, np.ndarray]  # ppm m
    path_concentration_sigma_ppm_m: Dict[str, np.ndarray]
    chi2: np.ndarray
    condition_number: np.ndarray
    iterations: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def peak_fraction(self) -> Dict[str, np.ndarray]:
        """Peak volume fraction x_i,peak per species."""
        return {s: self.parameters[..., k] for k, s in enumerate(self.species)}

    @property
    def peak_fraction_sigma(self) -> Dict[str, np.ndarray]:
        return {s: self.parameter_sigma[..., k] for k, s in enumerate(self.species)}

    @property
    def peak_temperature_K(self) -> np.ndarray:
        return self.parameters[..., len(self.species)]

    @property
    def peak_temperature_sigma_K(self) -> np.ndarray:
        return self.parameter_sigma[..., len(self.species)]

    @property
    def sigma_m(self) -> np.ndarray:
        """Gaussian plume depth sigma [m] (FWHM = 2.3548 sigma)."""
        return self.parameters[..., len(self.species) + 1]

    @property
    def sigma_sigma_m(self) -> np.ndarray:
        return self.parameter_sigma[..., len(self.species) + 1]

    @property
    def valid(self) -> np.ndarray:
        """Pixels with a solution (converged or on a bound)."""
        return (self.status == CONVERGED) | (self.status == AT_BOUND)

    def masked(self, values, include_below_detection: bool = False) -> np.ma.MaskedArray:
        """``values`` (an array of this result) masked outside the usable
        pixels (converged, at a bound, and optionally below detection)."""
        ok = self.valid | (include_below_detection & (self.status == BELOW_DETECTION))
        v = np.asarray(values)
        mask = ~ok
        while mask.ndim < v.ndim:
            mask = mask[..., None]
        return np.ma.masked_array(v, mask=np.broadcast_to(mask, v.shape))

    def counts(self) -> Dict[str, int]:
        """Number of pixels per status."""
        return {name: int(np.sum(self.status == k)) for k, name in enumerate(STATUS_NAMES)}

    def frame_mean(self, species: str) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per pixel over frames (leading axis): mean column density [kg/m2]
        of the frames with a solution or below detection (those count as 0),
        its 1-sigma uncertainty sqrt(sum sigma^2) / n, and n."""
        if self.status.ndim < 2:
            raise ValueError("frame_mean needs a frame axis (a result of invert_frames)")
        use = self.valid | (self.status == BELOW_DETECTION)
        n = use.sum(axis=0)
        c = np.where(use, self.column_density[species], 0.0).sum(axis=0)
        v = np.where(use, self.column_density_sigma[species] ** 2, 0.0).sum(axis=0)
        nn = np.maximum(n, 1)
        return c / nn, np.sqrt(v) / nn, n


# ---------------------------------------------------------------------------
# The inversion


#: InversionResult fields per pixel: arrays, and dicts of arrays per species.
_RESULT_ARRAYS = (
    "status",
    "bound_mask",
    "flags",
    "parameters",
    "parameter_sigma",
    "covariance",
    "chi2",
    "condition_number",
    "iterations",
)
_RESULT_DICTS = (
    "column_density",
    "column_density_sigma",
    "path_concentration_ppm_m",
    "path_concentration_sigma_ppm_m",
)


def merge_results(a, b, sel: np.ndarray):
    """InversionResult ``a`` (pixels on the first axis) with the pixels
    selected by ``sel`` taken from ``b``."""
    out = copy.copy(a)
    for name in _RESULT_ARRAYS:
        x = np.array(getattr(a, name))
        x[sel] = np.asarray(getattr(b, name))[sel]
        setattr(out, name, x)
    for name in _RESULT_DICTS:
        d = {}
        for sp, v in getattr(a, name).items():
            x = np.array(v)
            x[sel] = np.asarray(getattr(b, name)[sp])[sel]
            d[sp] = x
        setattr(out, name, d)
    return out


def writable_copy(result):
    """A copy of an InversionResult whose arrays may be written."""
    out = copy.copy(result)
    for name in _RESULT_ARRAYS:
        setattr(out, name, np.array(getattr(result, name)))
    for name in _RESULT_DICTS:
        setattr(out, name, {sp: np.array(v) for sp, v in getattr(result, name).items()})
    return out


def scatter_results(full, part, idx: np.ndarray) -> None:
    """Writes InversionResult ``part`` (pixels ``idx`` of ``full``) into ``full``."""
    for name in _RESULT_ARRAYS:
        getattr(full, name)[idx] = getattr(part, name)
    for name in _RESULT_DICTS:
        for sp, v in getattr(part, name).items():
            getattr(full, name)[sp][idx] = v


class Inversion:
    """Inverts pixels' band radiances for Gaussian-plume parameters.

    Parameters
    ----------
    model : ForwardModel
        Channels, species and cross-section tables.
    ambient_temperature_K : float, K
        T_amb of the scene (the plume's edges).
    netd_K : float or sequence, K
        NETD, one value or one per channel (the noise model above).
    fractions : dict, optional
        ``{species: spec}`` with spec a number (fixed), ``"free"``, or
        :func:`fixed`/:func:`free`/:func:`prior`/:func:`tied`; species left
        out are fixed at 0. Default: every species free in [0, 1].
    temperature : "ambient", number, "free" or Parameter, optional
        T_peak [K]. Default: ``"ambient"`` (fixed) with one channel,
        ``free()`` within ``ambient + (-10, +100) K`` with several.
    sigma_m : number or Parameter, m, default 0.05
        Plume depth sigma (per-pixel values may be given to :meth:`invert`,
        e.g. from :func:`plume_depth_from_width`). Default bounds when
        estimated: [1e-4 m, max_sigma_m].
    temperature_range_K : (float, float), optional
        Peak temperatures the table must cover when per-pixel temperatures
        are given to :meth:`invert` (default: from ``temperature``).
    max_sigma_m : float, m, default 2
        Largest plume depth the table covers.
    detection_sigma : float, default 3
        k of the detection test |y_c| < k n_c (in every channel).
    signed_below_detection : bool, default False
        Below the test, a pixel's column is 0; with this, its thin-limit
        least-squares column from the contrasts, signed and noisy
        (unbiased: summed over many pixels, a faint plume's wings are kept).
        Its status stays below detection, its sigma the noise-equivalent
        column.
    model_error_fraction : float, default 0
        Relative model uncertainty added in quadrature to each channel's noise.
    initial_guess : {"table", "neighbour", "previous"}, default "table"
        Coarse table lookup, the previous pixel of the same image row, or (for
        frame sequences) the same pixel's previous frame; warm starts fall back
        to the table guess when they fail.
    solver : {"auto", "table", "full_model"}, default "auto"
    max_iterations : int, default 100
    cold_start : {"profile", "starts"}, default "profile"
        How a pixel is solved without a warm start when the temperature is
        free. With the temperature free the chi2 landscape often has two
        branches (thin and hot, thick and cooler); both methods look for every
        minimum, and a second solution within chi2 + 4 widens the reported
        uncertainty (flag ``AMBIGUOUS``). ``"profile"``: chi2 profiled over
        T_peak (the fractions solved at each of the table's temperature nodes),
        every local minimum polished with all parameters free. ``"starts"``:
        full solves from several candidates of a coarse lookup (slower; see
        ``num_starts``).
    num_starts : int, default 0
        ``cold_start="starts"`` only: full solves from the coarse lookup's best
        candidates (0 = all of them).
    tolerance_chi2 : float, default 0.01
        Converged when a Gauss-Newton step would lower chi2 by less than this
        (the parameters are then within ~0.1 standard deviation of the optimum).
    table_options : dict, optional
        Further options of :func:`scene_table`.
    table : SceneTable, optional
        A table already built by :func:`scene_table` for the same model and
        ambient temperature, covering this inversion's peak temperatures and
        depths (several inversions of one scene share it; building one takes
        seconds). Default: built here.
    num_threads : int, default 0 (all cores)
    progress : callable(fraction) -> bool or None, optional
        Progress of the table build; return False to cancel.
    """

    def __init__(
        self,
        model: ForwardModel,
        ambient_temperature_K: float,
        *,
        netd_K,
        fractions: Optional[Mapping[str, object]] = None,
        temperature=None,
        sigma_m: Union[float, Parameter] = 0.05,
        temperature_range_K: Optional[Tuple[float, float]] = None,
        max_sigma_m: float = 2.0,
        detection_sigma: float = 3.0,
        signed_below_detection: bool = False,
        model_error_fraction: float = 0.0,
        initial_guess: str = "table",
        solver: str = "auto",
        max_iterations: int = 100,
        tolerance_chi2: float = 0.01,
        num_starts: int = 0,
        cold_start: str = "profile",
        table_options: Optional[dict] = None,
        num_threads: int = 0,
        progress=None,
        table=None,
    ):
        if not isinstance(model, ForwardModel):
            raise ValueError(f"model must be a qogi.ForwardModel; got {type(model).__name__}")
        t_amb = float(ambient_temperature_K)
        lo_m, hi_m = model.temperature_range_K
        if not (np.isfinite(t_amb) and lo_m <= t_amb <= hi_m):
            raise ValueError(
                f"ambient_temperature_K must be within the tables' range "
                f"[{lo_m:g}, {hi_m:g}] K; got {ambient_temperature_K}"
            )
        self.model = model
        self.species = list(model.species)
        self.ambient_temperature_K = t_amb
        nc = len(model.channels)
        netd = np.atleast_1d(np.asarray(netd_K, dtype=float))
        if netd.size not in (1, nc) or np.any(~np.isfinite(netd)) or np.any(netd <= 0):
            raise ValueError(
                f"netd_K needs one positive value or one per channel ({nc}); got {netd_K}"
            )
        self.netd_K = netd
        # Fractions.
        if fractions is None:
            fr = {s: free() for s in self.species}
        else:
            unknown = set(fractions) - set(self.species)
            if unknown:
                raise ValueError(
                    f"fractions has species {sorted(unknown)} the model does not have; "
                    f"the model's species are {self.species}"
                )
            fr = {
                s: _as_parameter(fractions.get(s, 0.0), f"fractions[{s!r}]") for s in self.species
            }
        self.fractions = fr
        # Temperature.
        if temperature is None:
            temperature = "ambient" if nc == 1 else free()
        if isinstance(temperature, str) and temperature == "ambient":
            temperature = fixed(t_amb)
        self.temperature = _as_parameter(temperature, "temperature")
        self.sigma = _as_parameter(sigma_m, "sigma_m")
        # Table range of peak temperatures.
        t = self.temperature
        if t.mode == "fixed":
            t_fixed = t_amb if t.value is None else t.value  # the value _spec gives the engine
            lo, hi = t_fixed - 10.0, t_fixed + 10.0
        else:
            lo = t.lower if t.lower is not None else t_amb + DEFAULT_TEMPERATURE_SPAN_K[0]
            hi = t.upper if t.upper is not None else t_amb + DEFAULT_TEMPERATURE_SPAN_K[1]
        if temperature_range_K is not None:
            lo, hi = float(temperature_range_K[0]), float(temperature_range_K[1])
        lo, hi = max(lo, lo_m), min(hi, hi_m)
        if not hi - lo >= 5.0:
            raise ValueError(
                f"the peak temperature range [{lo:g}, {hi:g}] K (within the tables' "
                f"[{lo_m:g}, {hi_m:g}] K) is too narrow or empty"
            )
        self.temperature_range_K = (lo, hi)
        self.max_sigma_m = float(max_sigma_m)
        tb_opts = dict(table_options or {})
        if num_threads and "num_threads" not in tb_opts:
            tb_opts["num_threads"] = num_threads
        guesses = {
            "table": _engine.InitialGuess.table,
            "neighbour": _engine.InitialGuess.neighbour,
            "previous": _engine.InitialGuess.previous,
        }
        if initial_guess not in guesses:
            raise ValueError(
                f"initial_guess must be one of {sorted(guesses)}; got {initial_guess!r}"
            )
        colds = {"profile": _engine.ColdStart.profile, "starts": _engine.ColdStart.starts}
        if cold_start not in colds:
            raise ValueError(f"cold_start must be one of {sorted(colds)}; got {cold_start!r}")
        solvers = {
            "auto": _engine.SolverKind.auto,
            "table": _engine.SolverKind.table,
            "full_model": _engine.SolverKind.full_model,
        }
        if solver not in solvers:
            raise ValueError(f"solver must be one of {sorted(solvers)}; got {solver!r}")
        # Validate the specifications before the (seconds-long) table build.
        for sp in self.species:
            _spec(self.fractions[sp], 1e-3, (0.0, 1.0), self.species)
        if (
            not any(self.fractions[sp].mode in ("free", "prior") for sp in self.species)
            and self.temperature.mode == "fixed"
            and self.sigma.mode == "fixed"
        ):
            raise ValueError(
                "every parameter is fixed: make at least one species' fraction, the "
                "temperature or sigma free"
            )
        self.table = None
        if table is not None and solver != "full_model":
            t_lo, t_hi = table.min_peak_temperature_K, table.max_peak_temperature_K
            if not (
                t_lo <= lo + 1e-9
                and hi <= t_hi + 1e-9
                and table.options.max_sigma_m >= self.max_sigma_m - 1e-12
            ):
                raise ValueError(
                    f"table covers peak temperatures [{t_lo:g}, {t_hi:g}] K and depths "
                    f"up to {table.options.max_sigma_m:g} m; this inversion needs [{lo:g}, "
                    f"{hi:g}] K and {self.max_sigma_m:g} m: build it with "
                    "scene_table(..., min_peak_temperature_K, max_peak_temperature_K, "
                    "max_sigma_m) covering them"
                )
            self.table = table
        elif solver != "full_model":
            self.table = scene_table(
                model,
                t_amb,
                min_peak_temperature_K=lo,
                max_peak_temperature_K=hi,
                max_sigma_m=self.max_sigma_m,
                progress=progress,
                **tb_opts,
            )
            if self.table is None and solver == "table":
                raise ValueError(
                    "solver 'table' needs spectrally separate species: "
                    + "; ".join(_engine.spectral_overlaps(model.fast))
                    + "; use solver='full_model'"
                )
        self._settings: Dict[str, Any]  # InversionOptions' other keyword arguments
        self._settings = dict(
            num_starts=int(num_starts),
            detection_sigma=float(detection_sigma),
            signed_below_detection=bool(signed_below_detection),
            model_error_fraction=float(model_error_fraction),
            max_iterations=int(max_iterations),
            tolerance_chi2=float(tolerance_chi2),
            solver=solvers[solver],
            num_threads=int(num_threads),
            cold_start=colds[cold_start],
        )
        self._guess = guesses[initial_guess]
        self.initial_guess = initial_guess
        self._inverters: Dict[tuple, object] = {}
        # Build once now so that bad settings fail here.
        self._inverter(self._guess, 1.0)

    # -- engine objects ---------------------------------------------------------
    def _options(self, guess, noise_scale: float):
        specs = []
        for s in self.species:
            specs.append(_spec(self.fractions[s], 1e-3, (0.0, 1.0), self.species))
        t_lo, t_hi = self.temperature_range_K
        tspec = _spec(self.temperature, self.ambient_temperature_K, (t_lo, t_hi))
        sspec = _spec(self.sigma, 0.05, (1e-4, self.max_sigma_m))
        netd = list(self.netd_K * noise_scale)
        return _engine.InversionOptions(
            fractions=specs,
            temperature=tspec,
            sigma=sspec,
            netd_K=netd,
            initial_guess=guess,
            **self._settings,
        )

    def _inverter(self, guess, noise_scale: float):
        key = (int(guess), float(noise_scale))
        inv = self._inverters.get(key)
        if inv is None:
            # The binding takes a None table (std::shared_ptr<SceneTable>: the
            # full-model solver); the generated stub types it SceneTable only.
            inv = _engine.Inverter(
                self.model.fast,
                self.table,  # type: ignore[arg-type]
                self.ambient_temperature_K,
                self._options(guess, noise_scale),
            )
            self._inverters[key] = inv
        return inv

    @property
    def uses_table(self) -> bool:
        """Whether pixels are solved on the per-scene table (else the full model)."""
        return bool(self._inverter(self._guess, 1.0).uses_table)

    @property
    def parameter_names(self) -> list:
        return [f"x_{s}" for s in self.species] + ["peak_temperature_K", "sigma_m"]

    def channel_noise(self, background_temperature_K) -> np.ndarray:
        """Radiance noise n_c [W/(m2 sr)] per channel at background temperatures."""
        inv = self._inverter(self._guess, 1.0)
        t = np.broadcast_to(
            np.asarray(background_temperature_K, dtype=float), (len(self.model.channels),)
        )
        return np.array([inv.channel_noise(c, float(t[c])) for c in range(len(t))])

    # -- inputs -----------------------------------------------------------------
    def _per_pixel(self, a, name: str, spatial: Tuple[int, ...]) -> np.ndarray:
        arr = np.asarray(a, dtype=float)
        try:
            out = np.broadcast_to(arr, spatial)
        except ValueError:
            raise ValueError(
                f"{name} has shape {arr.shape}; expected the pixel shape {spatial}"
            ) from None
        return out.reshape(-1)

    def _background(self, a, name: str, spatial: Tuple[int, ...], frames: Optional[int]):
        """(F or 1, C, N) from a per-channel array (C,), an image (C, ...), or
        per-frame images (T, C, ...) when frames is given."""
        nc = len(self.model.channels)
        arr = np.asarray(a, dtype=float)
        if frames is not None and arr.ndim == len(spatial) + 2:
            if arr.shape[0] != frames:
                raise ValueError(f"{name} has {arr.shape[0]} frames; the radiance has {frames}")
            arr3 = arr
        else:
            if arr.ndim == 1 and arr.shape[0] == nc:
                arr = arr.reshape((nc,) + (1,) * len(spatial))
            try:
                arr3 = np.broadcast_to(arr, (nc,) + spatial)[None]
            except ValueError:
                raise ValueError(
                    f"{name} has shape {arr.shape}; expected {(nc,) + spatial}, "
                    f"({nc},) or per frame"
                ) from None
        return arr3.reshape(arr3.shape[0], nc, -1)

    def _run(
        self,
        radiance,
        frame_axis: bool,
        *,
        background_radiance,
        background_temperature_K,
        mask,
        sigma_m,
        peak_temperature_K,
        guess,
        noise_scale,
        progress,
    ):
        nc = len(self.model.channels)
        rad = np.asarray(radiance, dtype=float)
        lead = 1 if frame_axis else 0
        if rad.ndim < 1 + lead or rad.shape[lead] != nc:
            where = "(T, C, ...)" if frame_axis else "(C, ...)"
            raise ValueError(
                f"radiance must be {where} with C = {nc} channels; got shape {rad.shape}"
            )
        frames = rad.shape[0] if frame_axis else 1
        spatial = rad.shape[lead + 1 :]
        if (background_radiance is None) == (background_temperature_K is None):
            raise ValueError("give exactly one of background_radiance and background_temperature_K")
        rad3: np.ndarray = rad.reshape((frames, nc, -1))
        n = rad3.shape[2]
        use_l = background_radiance is not None
        bg = self._background(
            background_radiance if use_l else background_temperature_K,
            "background_radiance" if use_l else "background_temperature_K",
            spatial,
            frames if frame_axis else None,
        )
        sel = None
        if mask is not None:
            m = np.asarray(mask, dtype=bool)
            if m.shape != spatial:
                raise ValueError(f"mask has shape {m.shape}; expected the pixel shape {spatial}")
            sel = np.flatnonzero(m.reshape(-1))
        sg = None if sigma_m is None else self._per_pixel(sigma_m, "sigma_m", spatial)
        tp = (
            None
            if peak_temperature_K is None
            else self._per_pixel(peak_temperature_K, "peak_temperature_K", spatial)
        )
        if tp is not None:
            lo, hi = self.temperature_range_K
            bad = (~np.isfinite(tp)) | (tp < lo) | (tp > hi)
            if np.any(bad if sel is None else bad[sel]):
                raise ValueError(
                    f"peak_temperature_K values must lie within the table's range "
                    f"[{lo:g}, {hi:g}] K (set temperature_range_K); got "
                    f"{np.nanmin(tp):g}-{np.nanmax(tp):g} K"
                )
        if sg is not None:
            bad = (~np.isfinite(sg)) | (sg <= 0) | (sg > self.max_sigma_m)
            if np.any(bad if sel is None else bad[sel]):
                raise ValueError(
                    f"sigma_m values must be finite and within (0, "
                    f"{self.max_sigma_m:g}] m (max_sigma_m)"
                )
        if sel is not None:
            rad3 = rad3[:, :, sel]
            bg = bg[:, :, sel]
            sg = None if sg is None else sg[sel]
            tp = None if tp is None else tp[sel]
        row = spatial[-1] if len(spatial) >= 2 and sel is None else 0
        inv = self._inverter(guess, noise_scale)
        kw = dict(
            sigma_m=None if sg is None else np.ascontiguousarray(sg),
            peak_temperature_K=None if tp is None else np.ascontiguousarray(tp),
            row_length=row,
            progress=progress,
        )
        kw["background_radiance" if use_l else "background_temperature_K"] = np.ascontiguousarray(
            bg
        )
        out = inv.invert(np.ascontiguousarray(rad3), **kw)
        if sel is not None:
            full = {}
            for k, v in out.items():
                a = np.zeros((frames, n) + v.shape[2:], dtype=v.dtype)
                a[:, sel] = v
                full[k] = a
            full["status"][:, np.setdiff1d(np.arange(n), sel)] = MASKED
            out = full
        shape = ((frames,) if frame_axis else ()) + spatial

        def rs(a):
            return a.reshape(shape + a.shape[2:])

        col, csig = rs(out["column_density"]), rs(out["column_density_sigma"])
        ppm, psig = rs(out["path_concentration"]), rs(out["path_concentration_sigma"])
        sp = self.species
        return InversionResult(
            species=list(sp),
            status=rs(out["status"]),
            bound_mask=rs(out["bound_mask"]),
            flags=rs(out["flags"]),
            parameter_names=self.parameter_names,
            parameters=rs(out["parameters"]),
            parameter_sigma=rs(out["parameter_sigma"]),
            covariance=rs(out["covariance"]),
            column_density={s: col[..., k] for k, s in enumerate(sp)},
            column_density_sigma={s: csig[..., k] for k, s in enumerate(sp)},
            path_concentration_ppm_m={s: ppm[..., k] for k, s in enumerate(sp)},
            path_concentration_sigma_ppm_m={s: psig[..., k] for k, s in enumerate(sp)},
            chi2=rs(out["chi2"]),
            condition_number=rs(out["condition_number"]),
            iterations=rs(out["iterations"]),
            info=dict(num_channels=nc, noise_scale=noise_scale, uses_table=bool(inv.uses_table)),
        )

    # -- public -----------------------------------------------------------------
    def invert(
        self,
        radiance,
        *,
        background_radiance=None,
        background_temperature_K=None,
        mask=None,
        sigma_m=None,
        peak_temperature_K=None,
        progress=None,
    ) -> InversionResult:
        """Invert one image (or a set of pixels).

        Parameters
        ----------
        radiance : array (C, ...), W/(m2 sr)
            Band radiance per channel: (C,), (C, N) or (C, H, W).
        background_radiance : array, W/(m2 sr), optional
            The gas-free background per channel: same shape, or (C,).
        background_temperature_K : array, K, optional
            Or the background as a blackbody temperature per channel.
        mask : bool array (...), optional
            Pixels to invert (the others get status ``masked``).
        sigma_m, peak_temperature_K : array (...), optional
            Per-pixel plume depth [m] and peak temperature [K]: the fixed
            value, prior mean or start value of those parameters.
        progress : callable(fraction) -> bool or None, optional
            Return False to cancel (Ctrl-C also cancels).

        Returns
        -------
        InversionResult
        """
        return self._run(
            radiance,
            False,
            background_radiance=background_radiance,
            background_temperature_K=background_temperature_K,
            mask=mask,
            sigma_m=sigma_m,
            peak_temperature_K=peak_temperature_K,
            guess=self._guess,
            noise_scale=1.0,
            progress=progress,
        )

    def invert_frames(
        self,
        frames,
        *,
        background_radiance=None,
        background_temperature_K=None,
        mask=None,
        sigma_m=None,
        peak_temperature_K=None,
        warm_start: bool = True,
        progress=None,
    ) -> InversionResult:
        """Invert every frame of ``frames`` (T, C, ...); the background is one
        image (C, ...) / (C,) or one per frame (T, C, ...).

        With ``warm_start`` each pixel starts from its own solution in the
        previous frame (falling back to the table guess when that fails).
        Averaging the per-frame column densities
        (:meth:`InversionResult.frame_mean`) is the order of averaging that
        stays unbiased when the contrast-column relation is nonlinear;
        compare :meth:`invert_mean`.
        """
        guess = _engine.InitialGuess.previous if warm_start else self._guess
        return self._run(
            frames,
            True,
            background_radiance=background_radiance,
            background_temperature_K=background_temperature_K,
            mask=mask,
            sigma_m=sigma_m,
            peak_temperature_K=peak_temperature_K,
            guess=guess,
            noise_scale=1.0,
            progress=progress,
        )

    def invert_mean(
        self,
        frames,
        *,
        background_radiance=None,
        background_temperature_K=None,
        mask=None,
        sigma_m=None,
        peak_temperature_K=None,
        progress=None,
    ) -> InversionResult:
        """Invert the time-averaged image of ``frames`` (T, C, ...).

        The noise of the mean image is taken as NETD / sqrt(T) (independent
        frames). With a fluctuating plume this order of averaging is biased
        low, because the contrast is a concave function of the column (the
        contrast of the mean column exceeds the mean contrast); prefer
        :meth:`invert_frames` and :meth:`InversionResult.frame_mean`.
        """
        fr = np.asarray(frames, dtype=float)
        if fr.ndim < 2:
            raise ValueError(f"frames must be (T, C, ...); got shape {fr.shape}")
        t = fr.shape[0]
        bgr, bgt = background_radiance, background_temperature_K
        if bgt is not None and np.ndim(bgt) == fr.ndim:
            raise ValueError(
                "invert_mean needs one background image; average per-frame "
                "backgrounds as radiance and pass background_radiance"
            )
        if bgr is not None and np.ndim(bgr) == fr.ndim:
            bgr = np.mean(np.asarray(bgr, dtype=float), axis=0)
        return self._run(
            fr.mean(axis=0),
            False,
            background_radiance=bgr,
            background_temperature_K=bgt,
            mask=mask,
            sigma_m=sigma_m,
            peak_temperature_K=peak_temperature_K,
            guess=self._guess,
            noise_scale=1.0 / np.sqrt(t),
            progress=progress,
        )

    def __repr__(self) -> str:
        return (
            f"Inversion(species={self.species}, channels={len(self.model.channels)}, "
            f"T_amb={self.ambient_temperature_K:g} K, temperature={self.temperature}, "
            f"sigma={self.sigma}, uses_table={self.uses_table})"
        )


# ---------------------------------------------------------------------------
# Plume depth from the plume width


_line_inverters: Dict[int, tuple] = {}


def _line_inverter(table):
    """The engine's MixingLineInverter of ``table`` (it builds a band table
    per channel), cached like the tables."""
    with _tables_lock:
        hit = _line_inverters.get(id(table))
    if hit is not None and hit[0] is table:
        return hit[1]
    inverter = _engine.MixingLineInverter(table)
    with _tables_lock:
        if len(_line_inverters) >= 8:
            _line_inverters.pop(next(iter(_line_inverters)))
        _line_inverters[id(table)] = (table, inverter)
    return inverter


def _line_composition(model: ForwardModel, composition) -> np.ndarray:
    """The released gas's normalised volume fractions w_s per species of
    ``model`` (default: its only species)."""
    species = list(model.species)
    if composition is None:
        if len(species) != 1:
            raise ValueError(
                f"composition is needed with several species ({species}); e.g. "
                f"{{{species[0]!r}: 0.5, {species[1]!r}: 0.5}}"
            )
        composition = {species[0]: 1.0}
    missing = [sp for sp in species if sp not in composition]
    if missing:
        raise ValueError(f"composition lacks species {missing} of the model")
    w = np.array([float(composition[sp]) for sp in species])
    if not (np.all(np.isfinite(w)) and np.all(w >= 0) and w.sum() > 0):
        raise ValueError(f"composition fractions must be >= 0 and not all 0; got {composition}")
    return w / w.sum()


def _line_pixels(model: ForwardModel, radiance, background_radiance, sigma_m=None):
    """radiance (C, N), background broadcast to it, sigma_m broadcast to (N,)
    (None when not given), as float arrays; shapes checked."""
    rad = np.asarray(radiance, dtype=float)
    nc = len(model.channels)
    if rad.ndim != 2 or rad.shape[0] != nc:
        raise ValueError(f"radiance must be (C, N) with C = {nc}; got shape {rad.shape}")
    n = rad.shape[1]
    bg = np.broadcast_to(np.asarray(background_radiance, dtype=float).reshape(nc, -1), (nc, n))
    if sigma_m is None:
        return rad, bg, None
    sg = (
        np.broadcast_to(np.asarray(sigma_m, dtype=float).ravel(), (n,))
        if np.size(sigma_m) in (1, n)
        else None
    )
    if sg is None:
        raise ValueError(
            f"sigma_m must be one value or (N,) = ({n},); got shape {np.shape(sigma_m)}"
        )
    return rad, bg, sg


def invert_on_mixing_line(
    model: ForwardModel,
    table,
    slope_K_per_fraction: float,
    radiance,
    background_radiance,
    sigma_m,
    *,
    netd_K,
    composition: Optional[Dict[str, float]] = None,
    detection_sigma: float = 3.0,
    signed_below_detection: bool = False,
    num_threads: int = 0,
    progress=None,
) -> InversionResult:
    """Per-pixel inversion with one unknown, the released gas's total peak
    fraction X, on the plume's mixing line ``T_peak = T_amb + k X`` with a
    known composition ``x_s = w_s X`` and a given depth sigma.

    A gas that mixes adiabatically with ambient air has, at every point, a
    temperature excess proportional to its fraction (the Gaussian
    line-of-sight model has that shape): with the scene's slope ``k`` known,
    each pixel's channels determine X alone, by least squares on the
    per-scene table (engine: ``cpp/engine/inversion/mixing_line.h``; a
    coarse scan in ln X, then safeguarded Gauss-Newton). The 1-sigma of X is
    from the chi2's curvature along the line (NETD noise).

    Parameters
    ----------
    model : ForwardModel
    table : qogi._engine.SceneTable
        :func:`scene_table` of ``model`` (its ambient temperature is T_amb;
        where the line leaves its temperature range, T_peak is held at the
        range's end).
    slope_K_per_fraction : float, K
        k.
    radiance, background_radiance : array (C, N), W/(m2 sr)
    sigma_m : array (N,) or float, m
    netd_K : float or sequence (C,), K
    composition : dict, optional
        Volume fractions of the released gas per species of the model
        (normalised here); default: the model's only species.
    detection_sigma : float, default 3
        Below detection when |L - L_bg| < detection_sigma x noise in every
        channel (fractions and columns 0, sigma the thin-limit 1-sigma).
    signed_below_detection : bool, default False
        Below detection, the thin-limit least-squares X from the contrasts
        (signed, noisy; at ambient temperature) instead of 0, as
        :class:`Inversion`'s option of the same name.

    Returns
    -------
    InversionResult
        parameters: fractions w_s X, T_peak on the line, sigma (fixed);
        columns and path concentrations with their 1-sigma.
    """
    species = list(model.species)
    w = _line_composition(model, composition)
    rad, bg, sg = _line_pixels(model, radiance, background_radiance, sigma_m)
    n = rad.shape[1]
    nc = len(model.channels)
    netd = [float(v) for v in np.atleast_1d(netd_K)]
    out = _line_inverter(table).invert(
        np.ascontiguousarray(rad.T),
        np.ascontiguousarray(bg.T),
        np.ascontiguousarray(sg),
        float(slope_K_per_fraction),
        list(w),
        netd,
        float(detection_sigma),
        bool(signed_below_detection),
        num_threads=int(num_threads),
        progress=progress,
    )
    big_x, sx = out["fraction"], out["fraction_sigma"]
    tp, status = out["peak_temperature_K"], out["status"].astype(np.int8)
    t_amb = table.options.ambient_temperature_K
    below = status == BELOW_DETECTION
    failed = status == FAILED
    tp = np.where(below | failed, t_amb, tp)
    big_x = np.where(failed | (below & (not signed_below_detection)), 0.0, big_x)
    # Column per unit X and sigma on a 0.25 K grid of T_peak (eq. 6 is
    # linear in x and sigma; its profile integral depends on T_peak alone).
    slope = float(slope_K_per_fraction)
    t_lo, t_hi = table.min_peak_temperature_K, table.max_peak_temperature_K
    grid = np.linspace(t_lo, t_hi, max(2, int(np.ceil((t_hi - t_lo) / 0.25)) + 1))
    unit = model.column_density(
        {sp: np.ones_like(grid) for sp in species}, grid, np.ones_like(grid), t_amb
    )
    on_line = (t_amb + slope * big_x > t_lo) & (t_amb + slope * big_x < t_hi) & ~below & ~failed
    c0, dcol = {}, {}
    for k, sp in enumerate(species):
        f = np.interp(tp, grid, np.asarray(unit[sp]))
        df = np.interp(tp, grid, np.gradient(np.asarray(unit[sp]), grid))
        c0[sp] = w[k] * big_x * sg * f
        # d column / d X along the line (T_peak moves with X); below
        # detection: the thin limit at ambient.
        dcol[sp] = w[k] * sg * (f + np.where(on_line, big_x * df * slope, 0.0))
    npar = len(species) + 2
    params = np.zeros((n, npar))
    psig = np.zeros((n, npar))
    for k in range(len(species)):
        params[:, k] = w[k] * big_x
        psig[:, k] = w[k] * sx
    params[:, len(species)] = tp
    psig[:, len(species)] = np.where(on_line, abs(slope) * sx, 0.0)
    params[:, len(species) + 1] = sg
    column, column_sigma, ppm, ppm_sigma = {}, {}, {}, {}
    root = 1e6 * math.sqrt(2 * math.pi)
    for k, sp in enumerate(species):
        column[sp] = np.where(failed, 0.0, c0[sp])
        column_sigma[sp] = np.where(failed, 0.0, np.abs(dcol[sp]) * sx)
        ppm[sp] = root * params[:, k] * sg
        ppm_sigma[sp] = root * psig[:, k] * sg
    names = [f"x_{sp}" for sp in species] + ["peak_temperature_K", "sigma_m"]
    return InversionResult(
        species=species,
        status=status,
        bound_mask=np.zeros(n, np.uint8),
        flags=np.zeros(n, np.uint8),
        parameter_names=names,
        parameters=params,
        parameter_sigma=psig,
        covariance=np.zeros((n, 0, 0)),
        column_density=column,
        column_density_sigma=column_sigma,
        path_concentration_ppm_m=ppm,
        path_concentration_sigma_ppm_m=ppm_sigma,
        chi2=np.where(failed, 0.0, out["chi2"]),
        condition_number=np.zeros(n),
        iterations=out["iterations"],
        info=dict(num_channels=nc, mixing_line_K_per_fraction=slope, uses_table=True),
    )


@dataclass(frozen=True)
class MixingLineSlope:
    """The scene's mixing-line slope k (:func:`mixing_line_slope`).

    Attributes
    ----------
    found : bool
        False when fewer than ``min_samples`` pixel-frames reached
        ``min_snr`` (then k = 0 and its sigma 0: no search was made).
    slope_K_per_fraction, sigma_K_per_fraction : float, K per unit volume fraction
        k and its 1-sigma.
    num_candidates : int
        Pixel-frames at or above ``min_snr``.
    num_samples, num_fitted : int
        Of them, those solved on the line for each k, and those in the total
        (a finite chi2 at every k).
    grid_K_per_fraction, total_chi2 : array (K,)
        The profile: the k grid and the capped chi2 summed over the samples.
    """

    found: bool
    slope_K_per_fraction: float
    sigma_K_per_fraction: float
    num_candidates: int
    num_samples: int
    num_fitted: int
    grid_K_per_fraction: np.ndarray
    total_chi2: np.ndarray


def _slope(d: dict, num_candidates: Optional[int] = None) -> MixingLineSlope:
    return MixingLineSlope(
        found=bool(d["found"]),
        slope_K_per_fraction=float(d["slope_K_per_fraction"]),
        sigma_K_per_fraction=float(d["sigma_K_per_fraction"]),
        num_candidates=int(d["num_candidates"] if num_candidates is None else num_candidates),
        num_samples=int(d["num_samples"]),
        num_fitted=int(d["num_fitted"]),
        grid_K_per_fraction=np.asarray(d["grid_K_per_fraction"]),
        total_chi2=np.asarray(d["total_chi2"]),
    )


def mixing_line_slope(
    model: ForwardModel,
    table,
    radiance,
    background_radiance,
    sigma_m,
    *,
    netd_K,
    composition: Optional[Dict[str, float]] = None,
    detection_sigma: float = 3.0,
    min_snr: float = 10.0,
    max_samples: int = 3000,
    seed: int = 0,
    min_samples: int = 5,
    grid_step_K: float = 10.0,
    chi2_cap: float = 50.0,
    num_threads: int = 0,
    progress=None,
) -> MixingLineSlope:
    """The slope k of the scene's mixing line ``T_peak = T_amb + k X`` from
    its pixel-frames, with a known composition (engine:
    ``cpp/engine/inversion/mixing_line_slope.h``).

    A profile likelihood: the pixel-frames whose contrast reaches
    ``min_snr`` x noise in some channel (noise: NETD x dL/dT at the channel's
    median background temperature; at most ``max_samples`` of them, a random
    subset seeded by ``seed``) are solved on the line
    (:func:`invert_on_mixing_line`) for each k of a ``grid_step_K`` grid over
    the table's peak-temperature range minus T_amb; k minimises the summed
    chi2 (each pixel's capped at ``chi2_cap``), refined by a parabola through
    the best three nodes; its 1-sigma is where the profile rises by the reduced chi2 (>= 1) from its
    minimum, on the flatter side (at least half a grid step).

    Parameters
    ----------
    model : ForwardModel
    table : qogi._engine.SceneTable
        :func:`scene_table` of ``model``.
    radiance, background_radiance : array (C, N), W/(m2 sr)
        Pixel-frames (e.g. every frame's pixels side by side).
    sigma_m : array (N,) or float, m
        Gaussian plume depth per pixel-frame.
    netd_K : float or sequence (C,), K
    composition : dict, optional
        Volume fractions of the released gas per species (normalised here);
        default: the model's only species.
    detection_sigma : float, default 3
        As :func:`invert_on_mixing_line`.
    min_snr : float, default 10
    max_samples : int, default 3000
    seed : int, default 0
        Of the random subset when there are more candidates (the engine's
        own generator: the same subset on every platform).
    min_samples : int, default 5
        Fewer candidates: no search (``found`` False, k = 0).
    grid_step_K : float, default 10, K per unit fraction
    chi2_cap : float, default 50
    num_threads : int, default 0 (all cores)
    progress : callable(fraction) -> bool or None, optional
        Returning False cancels (KeyboardInterrupt).

    Returns
    -------
    MixingLineSlope
    """
    w = _line_composition(model, composition)
    rad, bg, sg = _line_pixels(model, radiance, background_radiance, sigma_m)
    out = _line_inverter(table).find_slope(
        np.ascontiguousarray(rad.T),
        np.ascontiguousarray(bg.T),
        np.ascontiguousarray(sg),
        list(w),
        [float(v) for v in np.atleast_1d(netd_K)],
        float(detection_sigma),
        num_threads=int(num_threads),
        min_snr=float(min_snr),
        max_samples=int(max_samples),
        seed=int(seed),
        min_samples=int(min_samples),
        grid_step_K=float(grid_step_K),
        chi2_cap=float(chi2_cap),
        progress=progress,
    )
    return _slope(out)


def mixing_line_slope_sample(
    model: ForwardModel,
    table,
    radiance,
    background_radiance,
    *,
    netd_K,
    min_snr: float = 10.0,
    max_samples: int = 3000,
    seed: int = 0,
) -> Tuple[np.ndarray, int]:
    """The pixel-frames :func:`mixing_line_slope` solves, for a caller with
    its own solver on the line (e.g. an unknown composition).

    radiance, background_radiance: (C, N) [W/(m2 sr)]; netd_K [K]. Returns
    (indices into N, increasing; the number of candidates at or above
    ``min_snr``)."""
    rad, bg, _ = _line_pixels(model, radiance, background_radiance)
    idx, count = _line_inverter(table).slope_sample(
        np.ascontiguousarray(rad.T),
        np.ascontiguousarray(bg.T),
        [float(v) for v in np.atleast_1d(netd_K)],
        float(min_snr),
        int(max_samples),
        int(seed),
    )
    return np.asarray(idx, dtype=np.int64), int(count)


def mixing_line_slope_from_profile(
    grid_K_per_fraction, chi2, *, chi2_cap: float = 50.0
) -> MixingLineSlope:
    """k and its 1-sigma (as :func:`mixing_line_slope`) from the chi2 of P
    pixels solved on the line at each of K evenly spaced slopes.

    grid_K_per_fraction: (K,) increasing [K per unit fraction]; chi2: (K, P)
    (pixels with a non-finite value at any k are left out). num_candidates
    of the result is P."""
    grid = [float(v) for v in np.asarray(grid_K_per_fraction, dtype=float).ravel()]
    chi = np.asarray(chi2, dtype=float)
    return _slope(
        _engine.mixing_line_slope_from_profile(grid, np.ascontiguousarray(chi), float(chi2_cap)),
        num_candidates=chi.shape[1] if chi.ndim == 2 else 0,
    )


def plume_depth_from_width(
    contrast, pixel_size_m: float, *, axis: int = -1, threshold: float = 0.0, cut: float = 0.2
) -> np.ndarray:
    """Gaussian depth sigma [m] of an axisymmetric plume from its width across
    the image.

    For an axisymmetric plume whose cross-section is Gaussian, the depth along
    the line of sight equals the width across it: the standard deviation of
    the plume's transverse profile. Along ``axis`` (across the plume) this
    keeps the samples of ``contrast`` (contrast, or a column density) above
    the level ``max(cut x peak, threshold)`` (noise in the wings would
    inflate a plain second moment), takes their second central moment
    (weights = values) and corrects it for the truncation: a Gaussian cut at
    z_c = sqrt(2 ln(peak / level)) has the moment

        sigma^2 (1 - 2 z_c phi(z_c) / (2 Phi(z_c) - 1))

    (0.69 sigma^2 at the default 20 % cut). Times ``pixel_size_m`` (the
    pixel's footprint at the plume: IFOV x distance). The cut falls between
    samples: a Gaussian comes out within 6 % at sigma = 1.5 samples, 4.5 %
    at 3, 2 % at 6.5; the profile must hold the plume down to the level (a
    profile cut short by its ends comes out narrow).

    Parameters
    ----------
    contrast : array (..., n)
        Profile(s) across the plume, positive for gas (e.g. rows of an image
        of a vertical plume); non-finite values count as 0.
    pixel_size_m : float, m
    axis : int, default -1
        The transverse axis.
    threshold : float, default 0
        Values at or below it (noise) do not count, in the units of
        ``contrast``.
    cut : float, default 0.2
        Values at or below ``cut`` x the profile's maximum do not count,
        in [0, 1).

    Returns
    -------
    ndarray
        sigma [m] per profile (the other axes); 0 where no value exceeds the
        level.
    """
    c = np.moveaxis(np.asarray(contrast, dtype=float), axis, -1)
    if not (np.isfinite(pixel_size_m) and pixel_size_m > 0):
        raise ValueError(f"pixel_size_m must be finite and > 0; got {pixel_size_m}")
    if not 0.0 <= cut < 1.0:
        raise ValueError(f"cut must be within [0, 1); got {cut}")
    p = np.where(np.isfinite(c), c, 0.0)
    peak = p.max(axis=-1, initial=0.0)
    level = np.maximum(cut * peak, threshold)
    w = np.where((p > level[..., None]) & (peak > 0)[..., None], p, 0.0)
    s = np.arange(c.shape[-1], dtype=float)
    tot = w.sum(axis=-1)
    safe = np.where(tot > 0, tot, 1.0)
    mean = (w * s).sum(axis=-1) / safe
    var = (w * (s - mean[..., None]) ** 2).sum(axis=-1) / safe
    # The truncation factor at z_c (1 without a level: z_c infinite).
    ratio = np.where((level > 0) & (tot > 0), level / np.where(peak > 0, peak, 1.0), 0.0)
    zc = np.sqrt(2.0 * np.log(1.0 / np.where(ratio > 0, ratio, 1.0)))
    phi = np.exp(-0.5 * zc * zc) / math.sqrt(2.0 * math.pi)
    big_phi = 0.5 * (1.0 + np.vectorize(math.erf, otypes=[float])(zc / math.sqrt(2.0)))
    factor = np.where(
        ratio > 0, 1.0 - 2.0 * zc * phi / np.maximum(2.0 * big_phi - 1.0, 1e-300), 1.0
    )
    return np.where(tot > 0, np.sqrt(var / np.maximum(factor, 1e-300)) * pixel_size_m, 0.0)
