"""Terms of the uncertainty budget that the pipeline sizes per scene.

* :func:`line_shape_ratios` / :func:`line_shape_systematic`: the ``line
  shape`` term. The Voigt wing rule and self-broadening of the cross-section
  tables are model choices (:class:`qogi.physics.forward.LineShape`); the retrieved
  column changes with them most where the plume is optically thick. The term
  is the largest relative change of the surface's flux-weighted columns when
  the same contrasts are read through each of the other rules.
* :func:`record_length_advice`: the record length a 10 % (1 sigma) mean
  needs, from the rate series' autocorrelation and the flux level's
  record-to-record scatter.
* :func:`direction_check`: a rate whose sign runs against the surfaces'
  orientation, or that is zero while gas crosses the surface, is flagged and
  its interval widened to what is known.

These are the terms' physics; the pipeline's stage that assembles a run's
rates and intervals with them is :mod:`qogi.pipeline.budget`.

See docs/pipeline_api.md ("Uncertainty budget") and docs/forward_model.md
("Line shape").
"""

from __future__ import annotations

import math
from typing import Callable, Dict, List, Optional, Sequence

import numpy as np

from ..physics.forward import LineShape, forward_model
from ..workers import current
from .flux_summary import FluxSummary

__all__ = [
    "AlternativeModels",
    "line_shape_ratios",
    "line_shape_systematic",
    "record_length_advice",
    "direction_check",
    "LEVEL_SCATTER_PER_STRUCTURE",
]


class AlternativeModels:
    """The forward models of the other line-shape rules, built on a worker
    thread while the run reads its frames: building a fast model (binning its
    cross-sections) is CPU work the run does not need until its budget, so it
    overlaps the reading instead of delaying the first block. Their
    cross-section tables are cached on disk."""

    def __init__(
        self, channels, species: Sequence[str], pressure_Pa: float, line_shape, start=None
    ):

        used = LineShape.parse(line_shape)
        self.rules = [
            LineShape(w, used.wing_cm1 if w == used.wing else 25.0, b)
            for w in ("fixed", "hapi")
            for b in (True, False)
        ]
        self.rules = [r for r in self.rules if r != used]
        self.models: List[object] = []
        self.error: Optional[BaseException] = None

        def build() -> None:
            try:
                for r in self.rules:
                    m = forward_model(channels, list(species), pressure_Pa, line_shape=r)
                    m.fast  # noqa: B018 (built here, on the worker)
                    self.models.append(m)
            except BaseException as e:  # reported with the term  # noqa: BLE001
                self.error = e

        # ``start(target, name) -> Thread``: the caller's owner of worker
        # threads, by default the current run's (qogi.workers: stopped and
        # awaited on every exit, Ctrl-C included: a thread left inside the
        # engine at interpreter exit aborts the process).
        if start is None:
            start = current().start
        self._job = start(build, "qogi-line-shapes")

    def get(self) -> list:
        """[(LineShape, ForwardModel)] (waits for the worker); raises its error."""
        self._job.join()
        if self.error is not None:
            raise self.error
        return list(zip(self.rules, self.models))


def fractions_of(cfg, species: str):
    """The peak fractions {species: x_s} a total fraction x means for a run:
    split by the known composition, else all of it in ``species``."""
    total = sum(cfg.composition[sp] for sp in cfg.species) if cfg.composition else None

    def fractions(x):
        if total is None:
            return {sp: (x if sp == species else np.zeros_like(x)) for sp in cfg.species}
        return {sp: x * cfg.composition[sp] / total for sp in cfg.species}

    return fractions


#: Plumes on the peak-fraction grid (1e-6 ... 1, log-spaced) along which
#: :func:`line_shape_ratios` compares the rules. Against 160, the term on
#: the validation's seed 0 reads within 5 % (the lab GF320 release's six
#: surfaces 0.167-0.202 of the rate, against 0.166-0.205) and 7 % (M150:
#: 0.017-0.022 against 0.018-0.023) at a quarter of the cost; each plume
#: costs one band radiance per rule.
LINE_SHAPE_GRID = 40


def line_shape_ratios(
    model,
    alternatives,
    channel: int,
    fractions_of_x: Callable[[np.ndarray], Dict[str, np.ndarray]],
    temperature_of_x: Callable[[np.ndarray], np.ndarray],
    sigma_m: float,
    ambient_K: float,
    background_K: float,
    alt_temperature_of_x: Optional[Callable[[np.ndarray], np.ndarray]] = None,
):
    """Column ratios between line-shape rules at equal contrast.

    Along the plume's family of Gaussian plumes (peak fraction x of the
    released gas on a log grid, ``fractions_of_x`` and ``temperature_of_x``
    give the species' fractions and the peak temperature; depth ``sigma_m``)
    the contrast of ``channel`` is computed with ``model`` and with each
    alternative model. A contrast read through the used model gives column
    c; the same contrast read through an alternative gives c'. Returns the
    used model's columns {species: (n,) [kg/m2]} and the ratios c'/c
    (n_alternatives, n), on the grid where the contrast is monotone. The
    ratios do not depend on the species (the same plumes' contrasts): with a
    known composition one call serves all species. ``alt_temperature_of_x``
    (default ``temperature_of_x``) reads the contrast at another peak
    temperature instead (qogi.pipeline.hotgas: the bias of an assumed temperature).
    """
    x = np.geomspace(1e-6, 1.0, LINE_SHAPE_GRID)
    fr = fractions_of_x(x)
    t = temperature_of_x(x)
    col_all = model.column_density(fr, t, sigma_m, ambient_K)
    base = model.background_radiance(background_K)[channel]

    t_alt = t if alt_temperature_of_x is None else alt_temperature_of_x(x)

    def contrast(m, tt=t):
        return np.abs(
            np.asarray(m.band_radiance(fr, tt, sigma_m, ambient_K, background_K))[:, channel] - base
        )

    c_used = contrast(model)
    keep = np.concatenate([[True], np.diff(c_used) > 0])
    cu = c_used[keep]
    # The ratios do not depend on the species; the first one with gas on
    # the grid indexes them.
    ref = next(
        (sp for sp in col_all if np.all(np.asarray(col_all[sp], float)[keep] > 0)),
        next(iter(col_all)),
    )
    col = np.asarray(col_all[ref], float)
    ratios = []
    for m in alternatives:
        c_alt = contrast(m, t_alt)
        ok = np.concatenate([[True], np.diff(c_alt) > 0])
        # The alternative's column at the used model's contrasts. Outside the
        # contrasts the alternative reaches on the grid the ratio of the
        # nearest one it reaches: beyond its saturation (no column gives the
        # contrast) and below its thinnest plume (where the ratio is the
        # thin limit's constant), not the ratio of its end column (which
        # would fall to 1 there).
        ca = c_alt[ok]
        # (Interpolated in log contrast and log column: exact in the thin
        # limit's proportion, and within 1.4 % of the inverse of a saturating
        # contrast on the 40-plume grid, where linear is 2.2 % off.)
        tiny = 1e-300
        ratio = np.exp(
            np.interp(np.log(cu + tiny), np.log(ca + tiny), np.log(col[ok] + tiny))
        ) / np.maximum(col[keep], tiny)
        inside = np.flatnonzero((cu >= ca[0]) & (cu <= ca[-1]))
        if inside.size:
            ratio[: inside[0]] = ratio[inside[0]]
            ratio[inside[-1] + 1 :] = ratio[inside[-1]]
        ratios.append(ratio)
    cols = {sp: np.asarray(v, float)[keep] for sp, v in col_all.items()}
    return cols, np.asarray(ratios)


def line_shape_systematic(
    columns: np.ndarray, weights: np.ndarray, grid_columns: np.ndarray, ratios: np.ndarray
) -> float:
    """Relative 1-sigma ``line shape`` term of one surface's rate.

    ``columns`` (T, N) [kg/m2] (NaN where not quantified) and ``weights``
    (T, N) (normal velocity x segment length) give the flux; each column is
    re-read through every alternative rule (``ratios`` at ``grid_columns``
    from :func:`line_shape_ratios`, interpolated in log column). The term is
    the largest relative change of the flux: the rules bracket the real
    (sub-Lorentzian) wings, so their largest deviation stands for one sigma.
    """
    return max(
        [abs(f - 1.0) for f in flux_ratios(columns, weights, grid_columns, ratios)], default=0.0
    )


def flux_ratios(
    columns: np.ndarray, weights: np.ndarray, grid_columns: np.ndarray, ratios: np.ndarray
) -> list:
    """The flux sum(c r(c) w) / sum(c w) for each row r of ``ratios`` (see
    :func:`line_shape_systematic`); 1.0 where there is no flux. (The
    pipeline keeps the same sums over a streamed run's blocks:
    :class:`qogi.pipeline.flux_summary.FluxSummary`.)"""

    c = np.asarray(columns, float)
    w = np.broadcast_to(np.asarray(weights, float), c.shape)
    return FluxSummary.of(c, np.zeros_like(c), w, np.ones(c.shape[1])).flux_ratios(
        grid_columns, ratios
    )


#: Relative record-to-record scatter of the transport flux level times the
#: square root of the number of plume structures that cross the surface in a
#: record (record length x mean normal speed / plume width). From the M150
#: validation (docs/validation.md): 2 s records scatter by 13.6 % (1 sigma of
#: the ten seeds' means; 6 s records by 5.5 %), and ~12 structures cross the
#: surfaces in 2 s (seed 0: speed and width at the surfaces as this module
#: measures them): 0.136 x sqrt(12) = 0.47.
LEVEL_SCATTER_PER_STRUCTURE = 0.47


def record_length_advice(
    rate_kg_s: np.ndarray,
    frame_rate_hz: float,
    n_effective: float,
    speed_m_s: float,
    width_m: float,
    target: float = 0.10,
) -> dict:
    """The record length a mean of relative 1-sigma ``target`` needs.

    Two parts shrink with the record length T as 1/sqrt(T): the temporal
    standard error (sd / sqrt(n_eff), n_eff from the rate series'
    autocorrelation) and the flux level's scatter
    (LEVEL_SCATTER_PER_STRUCTURE / sqrt(structures crossing in T), the
    structures' size the plume width at the surface). Returns
    ``{"record_s", "needed_s", "temporal", "level", "relative"}`` (relative
    1-sigma figures of this record)."""
    r = np.asarray(rate_kg_s, float)
    r = r[np.isfinite(r)]
    record_s = len(r) / frame_rate_hz if frame_rate_hz > 0 else float("nan")
    mean = float(np.mean(r)) if r.size else float("nan")
    if r.size < 3 or not mean > 0 or not record_s > 0:
        return {
            "record_s": record_s,
            "needed_s": float("nan"),
            "temporal": float("nan"),
            "level": float("nan"),
            "relative": float("nan"),
        }
    temporal = float(np.std(r, ddof=1)) / math.sqrt(max(1.0, n_effective)) / mean
    structures = record_s * abs(speed_m_s) / width_m if width_m > 0 else 0.0
    level = LEVEL_SCATTER_PER_STRUCTURE / math.sqrt(structures) if structures > 0 else 1.0
    rel = math.hypot(temporal, level)
    return {
        "record_s": record_s,
        "needed_s": record_s * (rel / target) ** 2,
        "temporal": temporal,
        "level": level,
        "relative": rel,
    }


def direction_check(
    rate_kg_s: np.ndarray, columns: np.ndarray, column_sigma: np.ndarray, weights_abs: np.ndarray
) -> Optional[dict]:
    """Whether a surface's rate contradicts the gas crossing it.

    ``rate_kg_s`` (T,) the per-frame rates, ``columns`` / ``column_sigma``
    (T, N) the surface's columns and their 1-sigma noise, ``weights_abs``
    (T, N) |normal speed| x segment length. Gas crosses the surface when the
    time-averaged column stands above its noise at some samples. Returns None
    when the rate is consistent, else ``{"reason", "bound_kg_s"}``: the
    reason ("zero" or "against"), and the magnitude that is known: the flux
    the columns would carry at the measured speeds taken as all outgoing
    (sum c |v_n| dl, averaged over the frames).
    """

    c = np.asarray(columns, float)
    w = np.broadcast_to(np.abs(np.asarray(weights_abs, float)), c.shape)
    rate = np.asarray(rate_kg_s, float)
    rate = rate[np.isfinite(rate)]
    mean = float(rate.mean()) if rate.size else 0.0
    return FluxSummary.of(c, column_sigma, w, np.ones(c.shape[1])).direction(mean)
