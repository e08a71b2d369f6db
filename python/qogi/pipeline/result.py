"""Results of a quantification: emission-rate time series per surface and
species, the mean with its 90 % interval, and exports (JSON, CSV, plots)."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from typing import Dict, List, Optional

import numpy as np

from ..audit import AUDIT_FIELDS, RECORD_SETTINGS
from ..diagnostics import Diagnostic, Diagnostics
from ..files import PathLike, atomic_open, atomic_path
from ..tables import summary_rows, to_dataframe, to_xarray

# Standard conditions and conversions live in qogi.units (one implementation);
# re-exported here for code that imported them from qogi.pipeline.result.
from ..units import (  # noqa: F401
    R_GAS,
    STANDARD_CONDITIONS,
    convert,
    is_volumetric,
    kg_s_to_slpm,
    parse_unit,
    standard_conditions_text,
    unit_slug,
)
from .surfaces import Surface

__all__ = ["SpeciesRate", "SurfaceResult", "Result", "STANDARD_CONDITIONS", "kg_s_to_slpm"]


def _f(x):
    """JSON-safe float (None for NaN/inf)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclasses.dataclass
class SpeciesRate:
    """Emission rate of one species through one surface.

    ``rate_kg_s`` is the per-frame series (NaN where a frame could not be
    quantified); ``mean_kg_h`` the mean rate and ``ci90_kg_h`` its 90 %
    interval (:func:`qogi.pipeline.budget.interval90`: the relative terms as
    a log-normal factor, so wider on the side away from zero);
    ``uncertainty_terms_kg_h`` the 1-sigma contributions and
    ``dominant_uncertainty`` the largest of them.
    """

    species: str
    time_s: np.ndarray
    rate_kg_s: np.ndarray
    mean_kg_h: float
    ci90_kg_h: tuple
    n_frames: int
    molar_mass_kg_mol: float
    uncertainty_terms_kg_h: Dict[str, float]
    dominant_uncertainty: str
    pixels_used: np.ndarray
    truth_kg_h: Optional[float] = None
    #: The smallest rate this surface could detect [kg/h] (qogi.pipeline.detection;
    #: None when not computed), and what it came from (``detection``: noise-
    #: equivalent column, velocity, pixels, confidence).
    detection_limit_kg_h: Optional[float] = None
    detection: Optional[dict] = None
    #: The error model's record (qogi.pipeline.error_model; None where it does
    #: not apply): its features, the expected error (rate / truth - 1), its
    #: spread and the budget's interval before the calibration.
    error_model: Optional[dict] = None
    #: Where in the operating envelope the rate was measured (the audit
    #: record's per-rate part, qogi.pipeline.budget._operating_point): the
    #: gas-background temperature difference, distance, gas speed, signal-
    #: to-noise, the error model's expected error and the probability of
    #: detection at the scene; None where not computed.
    operating_point: Optional[dict] = None

    @property
    def rate_kg_h(self) -> np.ndarray:
        return self.rate_kg_s * 3600.0

    @property
    def detected(self) -> Optional[bool]:
        """False when the mean rate is below the detection limit (the result
        is then "not detected, < :attr:`upper_limit_kg_h`"); None when no
        limit is known or nothing bounds the rate (an unbounded interval:
        the speed was not measured, and gas below the limit at the speed
        read may be gas above it at the true one)."""
        if self.detection_limit_kg_h is None or not math.isfinite(self.detection_limit_kg_h):
            return None
        if math.isinf(self.ci90_kg_h[1]):
            return None
        return bool(math.isfinite(self.mean_kg_h) and self.mean_kg_h >= self.detection_limit_kg_h)

    @property
    def upper_limit_kg_h(self) -> Optional[float]:
        """What "not detected, < X" says when the rate is not detected (None
        otherwise): the larger of the detection limit and the upper end of
        the 90 % interval. The decision compares the *mean* with the limit,
        and near the limit the mean reads low (the per-pixel test zeroes the
        plume's faint wings), so a truth up to ~1.4x the limit was read
        below it (docs/detection_limit.md); the interval's upper end is where
        the measurement itself puts the truth's bound."""
        if self.detected is not False:
            return None
        assert self.detection_limit_kg_h is not None  # detected is None without a limit
        hi = self.ci90_kg_h[1]
        if hi is None or not math.isfinite(hi):
            return float(self.detection_limit_kg_h)
        return float(max(self.detection_limit_kg_h, hi))

    def in_units(self, value_kg_h, unit: str):
        """A rate [kg/h] (scalar or array) in ``unit`` (qogi.units) for this species."""
        return convert(value_kg_h, unit, self.molar_mass_kg_mol)

    def text(self, unit: str = "kg/h") -> str:
        """The rate as people should read it: ``"1.23 kg/h [90% 1.1 .. 1.4]"``,
        or ``"not detected, < 0.05 kg/h"`` below the detection limit (the
        bound is :attr:`upper_limit_kg_h`)."""
        u = parse_unit(unit)
        upper = self.upper_limit_kg_h
        if upper is not None:
            return f"not detected, < {self.in_units(upper, u):.3g} {u}"
        lo, hi = (self.in_units(v, u) for v in self.ci90_kg_h)
        if math.isinf(hi):  # nothing bounds it: speed-not-measured, no-bound-without-speed
            return f"speed not measured, [90% {lo:.4g} .. unbounded] {u}"
        return f"{self.in_units(self.mean_kg_h, u):.4g} {u} [90% {lo:.4g} .. {hi:.4g}]"

    @property
    def mean_g_h(self) -> float:
        return self.mean_kg_h * 1000.0

    @property
    def mean_slpm(self) -> float:
        return kg_s_to_slpm(self.mean_kg_h / 3600.0, self.molar_mass_kg_mol)

    @property
    def sigma_kg_h(self) -> float:
        return math.sqrt(sum(v * v for v in self.uncertainty_terms_kg_h.values()))

    @property
    def error_vs_truth(self) -> Optional[float]:
        """(mean - truth) / truth, when the recording carries the truth."""
        if self.truth_kg_h is None or self.truth_kg_h == 0:
            return None
        return self.mean_kg_h / self.truth_kg_h - 1.0

    def to_dict(self) -> dict:
        d = {
            "mean_kg_h": _f(self.mean_kg_h),
            "ci90_kg_h": [_f(self.ci90_kg_h[0]), _f(self.ci90_kg_h[1])],
            "mean_g_h": _f(self.mean_g_h),
            "mean_slpm": _f(self.mean_slpm),
            "n_frames": int(self.n_frames),
            "uncertainty_terms_kg_h": {k: _f(v) for k, v in self.uncertainty_terms_kg_h.items()},
            "dominant_uncertainty": self.dominant_uncertainty,
            "time_s": [_f(t) for t in self.time_s],
            "rate_kg_h": [_f(r) for r in self.rate_kg_h],
            "pixels_used": [int(p) for p in self.pixels_used],
            "detection_limit_kg_h": _f(self.detection_limit_kg_h),
            "detected": self.detected,
            "upper_limit_kg_h": _f(self.upper_limit_kg_h),
            "detection": self.detection,
            "error_model": self.error_model,
            "operating_point": self.operating_point,
        }
        if self.truth_kg_h is not None:
            d["truth_kg_h"] = _f(self.truth_kg_h)
            d["error_vs_truth"] = _f(self.error_vs_truth)
        return d


@dataclasses.dataclass
class SurfaceResult:
    surface: Surface
    species: Dict[str, SpeciesRate]

    def to_dict(self) -> dict:
        d = self.surface.to_dict()
        d["species"] = {k: v.to_dict() for k, v in self.species.items()}
        return d


class Result:
    """What :func:`qogi.quantify` returns (see docs/pipeline_api.md)."""

    def __init__(
        self,
        surfaces: List[SurfaceResult],
        *,
        config,
        recording_path: str,
        pixel_status: Dict[str, int],
        maps: Optional[dict] = None,
        info: Optional[dict] = None,
        complete: bool = True,
        warnings: Optional[List[Diagnostic]] = None,
        audit: Optional[dict] = None,
        min_detectable_column: Optional[Dict[str, np.ndarray]] = None,
    ):
        self.surfaces = surfaces
        self._audit = dict(audit or {})
        #: Machine-readable warnings (:class:`qogi.diagnostics.Diagnostic`):
        #: what in this result cannot be fully trusted, and why.
        self.warnings = Diagnostics(warnings or [])
        self.config = config
        self.recording_path = recording_path
        self.pixel_status = dict(pixel_status)
        self._maps = maps or {}
        self._mdc = dict(min_detectable_column or {})
        self.info = dict(info or {})
        self.complete = complete
        self.standard_conditions = dict(STANDARD_CONDITIONS)
        self._units = "kg/h"

    @property
    def units(self) -> str:
        """The reporting unit of :meth:`summary`, the CSV's ``rate`` column and
        the JSON's ``mean``/``ci90``/``detection_limit`` (qogi.units; kg/h by
        default; volumetric units at :attr:`standard_conditions`)."""
        return self._units

    @units.setter
    def units(self, unit: str) -> None:
        self._units = parse_unit(unit)

    def __repr__(self) -> str:
        rates = "; ".join(
            f"{s.surface.name or k} {sp} {r.text(self.units)}"
            for k, s in enumerate(self.surfaces)
            for sp, r in s.species.items()
        )
        n = max((r.n_frames for s in self.surfaces for r in s.species.values()), default=0)
        return (
            f"<qogi.Result {os.path.basename(str(self.recording_path))}: "
            f"{len(self.surfaces)} surface(s), {n} frames"
            f"{'' if self.complete else ', PARTIAL'}"
            f"{f', {len(self.warnings)} warning(s)' if self.warnings else ''}: {rates}>"
        )

    @property
    def audit(self) -> dict:
        """The audit record (:mod:`qogi.audit`): the recording file's SHA-256,
        the recording's and the run's UTC times, qogi's version (stamped by
        :func:`qogi.quantify`; None where unknown) and the run's ``site``,
        ``component``, ``operator`` and ``location`` settings (None where not
        given)."""

        d = {k: self._audit.get(k) for k in AUDIT_FIELDS}
        cfg = self.config
        for k in RECORD_SETTINGS:
            d[k] = cfg.get(k) if isinstance(cfg, dict) else getattr(cfg, k, None)
        return d

    @audit.setter
    def audit(self, record: dict) -> None:
        """Stamp the record's own fields (:data:`qogi.audit.AUDIT_FIELDS`)."""

        unknown = sorted(set(record) - set(AUDIT_FIELDS))
        if unknown:
            raise KeyError(f"not fields of the audit record: {unknown}; known: {AUDIT_FIELDS}")
        self._audit = dict(record)

    # -- access --------------------------------------------------------------
    def maps(self, frame: int) -> dict:
        """Per-pixel maps of one recording frame (needs ``keep_maps=True``;
        about ten frames of a run keep them, :attr:`map_frames` lists them):
        ``column_density_kg_m2`` {first species: H x W}, the column field the
        velocimetry ran on (single-channel lookup at the assumed gas
        temperature: its shape is right, its scale approximate; the surfaces'
        own columns come from the full inversion), ``velocity_px_per_frame``
        (u, v; NaN outside the part where the flow was computed,
        ``velocity_region`` x0, y0, x1, y1 in the maps' pixels, end exclusive)
        and ``origin`` (x0, y0) of the maps in the frame."""
        if frame not in self._maps:
            raise KeyError(
                f"no maps kept for frame {frame}; run quantify(..., keep_maps=True) "
                f"(frames with maps: {sorted(self._maps)[:5]}...)"
            )
        return self._maps[frame]

    @property
    def min_detectable_column_species(self) -> List[str]:
        """The species :meth:`min_detectable_column` has a map of (none: truth
        columns, or a result read back from JSON)."""
        return list(self._mdc)

    def min_detectable_column(self, species: Optional[str] = None) -> np.ndarray:
        """The minimum-detectable column map [kg/m2], (H, W) in the recording's
        pixels: the column a pixel must hold to be seen in 95 % of the frames,
        ``(k + z) NEC`` at its own background temperature
        (:func:`qogi.pipeline.detection.min_detectable_column`; inf where the
        background has no contrast with the gas). ``species`` defaults to the
        run's first. Each surface's median of it is in its species'
        ``detection["min_detectable_column_kg_m2"]``."""
        if not self._mdc:
            raise ValueError(
                "this result has no minimum-detectable column map (truth columns, or a "
                "result read back from JSON): run qogi.quantify with inverted columns"
            )
        sp = species if species is not None else next(iter(self._mdc))
        if sp not in self._mdc:
            raise ValueError(f"no map for {sp!r}; species: {sorted(self._mdc)}")
        return self._mdc[sp]

    def draw_min_detectable_column(self, ax, species: Optional[str] = None, fontsize=8.0) -> None:
        """Draws :meth:`min_detectable_column` [g/m2] on matplotlib axes ``ax``
        with a colour bar and the surfaces, each labelled with its median
        (grey: no contrast, infinite)."""
        import matplotlib

        mdc = self.min_detectable_column(species)
        sp = species if species is not None else next(iter(self._mdc))
        g = np.where(np.isfinite(mdc), mdc * 1e3, np.nan)  # g/m2
        cmap = matplotlib.colormaps["cividis_r"].with_extremes(bad="0.75")
        im = ax.imshow(g, cmap=cmap, interpolation="nearest")
        cb = ax.figure.colorbar(im, ax=ax, fraction=0.035, pad=0.02)
        cb.set_label(f"{sp} minimum-detectable column [g/m2]", fontsize=fontsize)
        cb.ax.tick_params(labelsize=fontsize - 1)
        for k, s in enumerate(self.surfaces):
            p = np.asarray(s.surface.points)
            ax.plot(p[:, 0], p[:, 1], "-", color=f"C{k % 10}", lw=1.8)
            det = s.species[sp].detection if sp in s.species else None
            med = (det or {}).get("min_detectable_column_kg_m2")
            ax.annotate(
                s.surface.name + (f": {med * 1e3:.3g} g/m2" if med else ""),
                p[np.argmax(p[:, 0])],
                color=f"C{k % 10}",
                fontsize=fontsize,
                xytext=(4, 0),
                textcoords="offset points",
                va="center",
            )
        ax.set_xlim(-0.5, mdc.shape[1] - 0.5)
        ax.set_ylim(mdc.shape[0] - 0.5, -0.5)
        ax.set_title(
            f"{sp}: the column a pixel must hold to be seen in 95 % of frames",
            fontsize=fontsize + 0.5,
        )
        ax.tick_params(labelsize=fontsize - 1)

    @property
    def map_frames(self) -> List[int]:
        return sorted(self._maps)

    def total(self, species: str, surface: int = 0) -> SpeciesRate:
        return self.surfaces[surface].species[species]

    # -- exports -------------------------------------------------------------
    def to_dict(self) -> dict:
        cfg = self.config.to_dict() if hasattr(self.config, "to_dict") else dict(self.config)
        return {
            "format": "qogi-result",
            "version": 1,
            "recording": self.recording_path,
            "audit": self.audit,
            "complete": bool(self.complete),
            "warnings": [w.to_dict() for w in self.warnings],
            "standard_conditions": self.standard_conditions,
            "units": self.units,
            "config": cfg,
            "pixel_status": self.pixel_status,
            "info": {k: (_f(v) if isinstance(v, float) else v) for k, v in self.info.items()},
            "surfaces": [self._surface_dict(s) for s in self.surfaces],
        }

    def _surface_dict(self, s: SurfaceResult) -> dict:
        d = s.to_dict()
        for sp, r in s.species.items():
            # The summary numbers again in the reporting unit.
            d["species"][sp].update(
                {
                    "mean": _f(r.in_units(r.mean_kg_h, self.units)),
                    "ci90": [_f(r.in_units(v, self.units)) for v in r.ci90_kg_h],
                    "detection_limit": (
                        None
                        if r.detection_limit_kg_h is None
                        else _f(r.in_units(r.detection_limit_kg_h, self.units))
                    ),
                    "upper_limit": (
                        None
                        if r.upper_limit_kg_h is None
                        else _f(r.in_units(r.upper_limit_kg_h, self.units))
                    ),
                    "text": r.text(self.units),
                }
            )
        return d

    def to_json(self, path: Optional[PathLike] = None, indent: int = 2) -> str:
        """The result as JSON (schema: docs/pipeline_api.md); written to
        ``path`` when given. Returns the text."""
        text = json.dumps(self.to_dict(), indent=indent)
        if path is not None:
            with atomic_open(path, "w") as fh:
                fh.write(text + "\n")
        return text

    def to_csv(self, path: PathLike, summary: bool = True) -> None:
        """One row per frame, surface and species: time, rate (kg/h), pixels,
        and (units other than kg/h) ``rate_<unit>`` in :attr:`units`. With ``summary`` (default)
        also ``<name>.summary.csv`` beside it: one row per surface and species
        with the mean, the 90 % interval, the detection limit, whether it was
        detected, the unit and the standard conditions (see
        :meth:`summary_csv_path`)."""
        import csv

        extra = self.units != "kg/h"
        with atomic_open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(
                ["surface", "species", "time_s", "rate_kg_h", "pixels_used"]
                + ([f"rate_{unit_slug(self.units)}"] if extra else [])
            )
            for s in self.surfaces:
                for sp, r in s.species.items():
                    conv = r.in_units(r.rate_kg_h, self.units)
                    for t, v, n, c in zip(r.time_s, r.rate_kg_h, r.pixels_used, conv):
                        row = [
                            s.surface.name,
                            sp,
                            f"{t:.6f}",
                            "" if not np.isfinite(v) else f"{v:.6g}",
                            int(n),
                        ]
                        if extra:
                            row.append("" if not np.isfinite(c) else f"{c:.6g}")
                        w.writerow(row)
        if summary:
            self.to_summary_csv(self.summary_csv_path(path))

    @staticmethod
    def summary_csv_path(path: PathLike) -> str:
        """``out.csv`` -> ``out.summary.csv`` (where :meth:`to_csv` writes the summary)."""
        root, ext = os.path.splitext(os.fspath(path))
        return f"{root}.summary{ext or '.csv'}"

    def to_summary_csv(self, path: PathLike) -> None:
        """One row per surface and species: mean, 90 % interval and detection
        limit in :attr:`units` and in kg/h, detected, frames, dominant
        uncertainty, truth (synthetic recordings), unit and standard conditions."""
        import csv

        rows = summary_rows(self)
        with atomic_open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            cols = list(rows[0]) if rows else []
            w.writerow(cols + ["standard_conditions"])
            std = standard_conditions_text(self.standard_conditions)
            for row in rows:
                w.writerow(
                    [
                        "" if v is None else (f"{v:.6g}" if isinstance(v, float) else v)
                        for v in row.values()
                    ]
                    + [std]
                )

    def to_dataframe(self, summary: bool = False):
        """pandas DataFrame (needs pandas, ``pip install qogi[data]``): long
        format, one row per surface, species and frame (``surface``,
        ``species``, ``time_s``, ``rate_kg_h``, ``rate`` in :attr:`units`,
        ``pixels_used``); with ``summary=True`` one row per surface and species
        (mean, ci90_low, ci90_high, detection_limit in :attr:`units`, the same
        in kg/h, detected, n_frames, dominant_uncertainty, truth_kg_h).
        ``df.attrs`` holds the unit, standard conditions and recording."""

        return to_dataframe(self, summary=summary)

    def to_xarray(self):
        """xarray Dataset (needs xarray, ``pip install qogi[data]``) with
        dimensions surface, species, time: ``rate_kg_h`` and ``pixels_used``
        (surface, species, time), ``mean_kg_h``, ``ci90_low_kg_h``,
        ``ci90_high_kg_h``, ``detection_limit_kg_h`` (surface, species);
        attributes: units, standard conditions, recording, qogi version."""

        return to_xarray(self)

    def summary(self) -> str:
        """A few lines for people."""
        lines = [
            f"qogi result for {os.path.basename(str(self.recording_path))}"
            f"{'' if self.complete else ' (PARTIAL: cancelled or interrupted)'}"
        ]
        for s in self.surfaces:
            for sp, r in s.species.items():
                lo, hi = r.ci90_kg_h
                if self.units != "kg/h" or r.detected is False or math.isinf(hi):
                    line = f"  {s.surface.name:>12s} {sp:4s} {r.text(self.units)}"
                else:
                    line = (
                        f"  {s.surface.name:>12s} {sp:4s} {r.mean_kg_h:9.4g} kg/h "
                        f"[90% {lo:.4g} .. {hi:.4g}]  ({r.mean_g_h:.4g} g/h, "
                        f"{r.mean_slpm:.4g} SLPM)"
                    )
                line += f"  {r.n_frames} frames, dominant: {r.dominant_uncertainty}"
                if r.detection_limit_kg_h is not None and r.detected is not False:
                    line += (
                        f", detection limit "
                        f"{r.in_units(r.detection_limit_kg_h, self.units):.3g} {self.units}"
                    )
                pod90 = (r.operating_point or {}).get("pod_90_kg_h")
                if pod90 is not None:  # the probability of detection at this scene
                    line += (
                        f", detected 90 % of the time from "
                        f"{r.in_units(pod90, self.units):.3g} {self.units} here"
                    )
                if r.truth_kg_h is not None:
                    inside = lo <= r.truth_kg_h <= hi
                    err = r.error_vs_truth  # None for a zero truth (no relative error)
                    line += (
                        f"\n  {'':>12s}      truth {r.truth_kg_h:.4g} kg/h, error "
                        + ("n/a" if err is None else f"{100 * err:+.1f} %")
                        + ", truth "
                        f"{'inside' if inside else 'OUTSIDE'} the 90 % interval"
                    )
                lines.append(line)
        st = ", ".join(f"{k} {v}" for k, v in self.pixel_status.items())
        lines.append(f"  pixels: {st}")

        if self.units == "kg/h" or is_volumetric(self.units):
            lines.append(
                f"  volumes (SLPM, scfh, mcf/day) of the species at "
                f"{standard_conditions_text(self.standard_conditions)}"
            )
        for w in self.warnings:
            lines.append(f"  warning {w}")
        return "\n".join(lines)

    def plot(self, path: Optional[PathLike] = None, kind: str = "rates"):
        """A matplotlib figure: ``kind="rates"`` the emission-rate time series per
        surface and species with the mean and its 90 % band (and the truth);
        ``kind="maps"`` the column density and velocity of a kept frame;
        ``kind="detectability"`` the minimum-detectable column map with the
        surfaces (:meth:`min_detectable_column`)."""
        import matplotlib

        if path is not None:
            matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        if kind == "rates":
            species = sorted({sp for s in self.surfaces for sp in s.species})
            fig, axes = plt.subplots(
                len(species), 1, figsize=(9, 3.2 * len(species)), squeeze=False, sharex=True
            )
            for ax, sp in zip(axes[:, 0], species):
                for k, s in enumerate(self.surfaces):
                    if sp not in s.species:
                        continue
                    r = s.species[sp]
                    color = f"C{k % 10}"
                    ax.plot(
                        r.time_s,
                        r.rate_kg_h,
                        color=color,
                        lw=0.8,
                        alpha=0.8,
                        label=f"{s.surface.name}: {r.mean_kg_h:.3g} kg/h",
                    )
                    if r.time_s.size:
                        ax.axhline(r.mean_kg_h, color=color, lw=1.5)
                        if all(math.isfinite(v) for v in r.ci90_kg_h):
                            ax.axhspan(*r.ci90_kg_h, color=color, alpha=0.12)
                truth = next(
                    (
                        s.species[sp].truth_kg_h
                        for s in self.surfaces
                        if sp in s.species and s.species[sp].truth_kg_h is not None
                    ),
                    None,
                )
                if truth is not None:
                    ax.axhline(truth, color="k", ls="--", lw=1.2, label=f"truth {truth:.3g} kg/h")
                ax.set_ylabel(f"{sp} emission rate [kg/h]")
                ax.grid(alpha=0.3)
                ax.legend(fontsize=8, loc="upper right")
            axes[-1, 0].set_xlabel("time [s]")
            fig.suptitle("emission rate per surface (lines: mean; bands: 90 % interval)")
            fig.tight_layout()
        elif kind == "maps":
            if not self._maps:
                raise ValueError("no maps kept; run quantify(..., keep_maps=True)")
            f = self.map_frames[len(self.map_frames) // 2]
            m = self._maps[f]
            cols = m["column_density_kg_m2"]
            fig, axes = plt.subplots(
                1, len(cols) + 1, figsize=(5 * (len(cols) + 1), 4), squeeze=False
            )
            for ax, (sp, c) in zip(axes[0], cols.items()):
                im = ax.imshow(c * 1e3, cmap="magma", vmin=0)
                fig.colorbar(im, ax=ax, label=f"{sp} column density [g/m2]")
                for s in self.surfaces:
                    p = np.asarray(s.surface.points) - np.asarray(m.get("origin", (0, 0)))
                    ax.plot(p[:, 0], p[:, 1], "c-", lw=1.5)
                ax.set_title(f"frame {f}")
            u, v = m["velocity_px_per_frame"]
            total = sum(cols.values())
            gas = total > 0.05 * np.max(total) if np.max(total) > 0 else np.zeros_like(total, bool)
            gas = gas & np.isfinite(u) & np.isfinite(v)  # NaN: no flow computed there
            speed = np.where(gas, np.hypot(u, v), np.nan)
            ax = axes[0, -1]
            im = ax.imshow(speed, cmap="viridis")
            fig.colorbar(im, ax=ax, label="speed where there is gas [px/frame]")
            region = m.get("velocity_region")
            if region is not None:  # the flow's part of the maps; blank outside it
                x0, y0, x1, y1 = region
                ax.add_patch(
                    plt.Rectangle(
                        (x0 - 0.5, y0 - 0.5), x1 - x0, y1 - y0, fill=False, ec="0.4", ls="--"
                    )
                )
                ax.set_xlim(-0.5, u.shape[1] - 0.5)
                ax.set_ylim(u.shape[0] - 0.5, -0.5)
            step = max(1, min(u.shape) // 24)
            yy, xx = np.mgrid[0 : u.shape[0] : step, 0 : u.shape[1] : step]
            g = gas[::step, ::step]
            # Image axes run y down, as v does: the arrows need no flip.
            ax.quiver(
                xx[g], yy[g], u[::step, ::step][g], v[::step, ::step][g], color="k", angles="xy"
            )
            ax.set_title(
                "velocity (arrows: gas pixels;\ndashed: where the flow was computed)"
                if region is not None
                else "velocity (arrows: gas pixels)"
            )
            fig.tight_layout()
        elif kind == "detectability":
            if not self._mdc:
                self.min_detectable_column()  # raises, saying why there is no map
            fig, axes = plt.subplots(
                1, len(self._mdc), figsize=(6 * len(self._mdc), 4.4), squeeze=False
            )
            for ax, sp in zip(axes[0], self._mdc):
                self.draw_min_detectable_column(ax, sp)
            fig.tight_layout()
        else:
            raise ValueError(f"kind must be 'rates', 'maps' or 'detectability'; got {kind!r}")
        if path is not None:
            with atomic_path(path) as tmp:
                fig.savefig(tmp, dpi=110)
            plt.close(fig)
        return fig
