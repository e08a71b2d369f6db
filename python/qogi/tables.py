"""Results as tables: rows for CSV, pandas DataFrames and xarray Datasets.

pandas and xarray are optional (``pip install qogi[data]``); the functions
that need them say so when they are missing.
"""

from __future__ import annotations

import math
from typing import Dict, List

import numpy as np

from ._version import __version__

__all__ = ["summary_rows", "to_dataframe", "to_xarray"]


def _need(module: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(
            f"Result.to_{'dataframe' if module == 'pandas' else 'xarray'}() needs "
            f"{module}: pip install {module} (or pip install 'qogi[data]')"
        ) from e


def _num(x):
    return None if x is None or not math.isfinite(float(x)) else float(x)


def summary_rows(result) -> List[dict]:
    """One dict per surface and species: the summary numbers in the result's
    unit and in kg/h (None where unknown), then the audit record
    (:attr:`qogi.Result.audit`)."""
    u = result.units
    audit = result.audit  # the audit record on every row (qogi.audit)
    rows = []
    for s in result.surfaces:
        for sp, r in s.species.items():
            dl, up = r.detection_limit_kg_h, r.upper_limit_kg_h
            rows.append(
                {
                    "surface": s.surface.name,
                    "species": sp,
                    "units": u,
                    "mean": _num(r.in_units(r.mean_kg_h, u)),
                    "ci90_low": _num(r.in_units(r.ci90_kg_h[0], u)),
                    "ci90_high": _num(r.in_units(r.ci90_kg_h[1], u)),
                    "detection_limit": None if dl is None else _num(r.in_units(dl, u)),
                    "detected": r.detected,
                    "upper_limit": None if up is None else _num(r.in_units(up, u)),
                    "mean_kg_h": _num(r.mean_kg_h),
                    "ci90_low_kg_h": _num(r.ci90_kg_h[0]),
                    "ci90_high_kg_h": _num(r.ci90_kg_h[1]),
                    "detection_limit_kg_h": None if dl is None else _num(dl),
                    "upper_limit_kg_h": None if up is None else _num(up),
                    "n_frames": int(r.n_frames),
                    "dominant_uncertainty": r.dominant_uncertainty,
                    "truth_kg_h": None if r.truth_kg_h is None else _num(r.truth_kg_h),
                    **_operating_columns(r.operating_point),
                    **audit,
                }
            )
    return rows


#: The operating point's fields (``SpeciesRate.operating_point``) as summary
#: columns, in their order.
OPERATING_COLUMNS = (
    "delta_T_K",
    "distance_m",
    "speed_m_s",
    "snr",
    "expected_error",
    "pod_50_kg_h",
    "pod_90_kg_h",
    "pod_at_mean",
)


def _operating_columns(op) -> dict:
    """The operating point as summary columns (None where not stated)."""
    op = op or {}
    return {k: None if op.get(k) is None else _num(op[k]) for k in OPERATING_COLUMNS}


def _attrs(result) -> dict:

    # The audit record as text ("" where unknown: netCDF attributes hold no None).
    audit = {k: "" if v is None else str(v) for k, v in result.audit.items()}
    return {
        "units": result.units,
        "recording": str(result.recording_path),
        "standard_temperature_K": result.standard_conditions["temperature_K"],
        "standard_pressure_Pa": result.standard_conditions["pressure_Pa"],
        "complete": int(bool(result.complete)),
        **audit,
        "qogi_version": audit["qogi_version"] or __version__,
    }


def to_dataframe(result, summary: bool = False):
    """See :meth:`qogi.Result.to_dataframe`."""
    pd = _need("pandas")
    if summary:
        df = pd.DataFrame(summary_rows(result))
    else:
        parts = []
        for s in result.surfaces:
            for sp, r in s.species.items():
                n = len(r.time_s)
                parts.append(
                    pd.DataFrame(
                        {
                            "surface": [s.surface.name] * n,
                            "species": [sp] * n,
                            "time_s": np.asarray(r.time_s, float),
                            "rate_kg_h": np.asarray(r.rate_kg_h, float),
                            "rate": np.asarray(r.in_units(r.rate_kg_h, result.units), float),
                            "pixels_used": np.asarray(r.pixels_used, np.int64),
                        }
                    )
                )
        cols = ["surface", "species", "time_s", "rate_kg_h", "rate", "pixels_used"]
        df = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=cols)
    df.attrs.update(_attrs(result))
    return df


def to_xarray(result):
    """See :meth:`qogi.Result.to_xarray`."""
    xr = _need("xarray")
    names = [s.surface.name for s in result.surfaces]
    species = sorted({sp for s in result.surfaces for sp in s.species})
    time = next(
        (np.asarray(r.time_s, float) for s in result.surfaces for r in s.species.values()),
        np.zeros(0),
    )
    ns, nk, nt = len(names), len(species), len(time)
    rate = np.full((ns, nk, nt), np.nan)
    pixels = np.zeros((ns, nk, nt), np.int64)
    per = {
        k: np.full((ns, nk), np.nan)
        for k in (
            "mean_kg_h",
            "ci90_low_kg_h",
            "ci90_high_kg_h",
            "detection_limit_kg_h",
            "upper_limit_kg_h",
            "truth_kg_h",
        )
    }
    for i, s in enumerate(result.surfaces):
        for sp, r in s.species.items():
            j = species.index(sp)
            rate[i, j, : len(r.rate_kg_h)] = r.rate_kg_h
            pixels[i, j, : len(r.pixels_used)] = r.pixels_used
            per["mean_kg_h"][i, j] = r.mean_kg_h
            per["ci90_low_kg_h"][i, j], per["ci90_high_kg_h"][i, j] = r.ci90_kg_h
            if r.detection_limit_kg_h is not None:
                per["detection_limit_kg_h"][i, j] = r.detection_limit_kg_h
            if r.upper_limit_kg_h is not None:
                per["upper_limit_kg_h"][i, j] = r.upper_limit_kg_h
            if r.truth_kg_h is not None:
                per["truth_kg_h"][i, j] = r.truth_kg_h
    dims3, dims2 = ("surface", "species", "time"), ("surface", "species")
    data: Dict[str, tuple] = {
        "rate_kg_h": (dims3, rate, {"units": "kg/h", "long_name": "emission rate per frame"}),
        "pixels_used": (dims3, pixels, {"long_name": "surface samples with a column"}),
    }
    for k, v in per.items():
        data[k] = (dims2, v, {"units": "kg/h"})
    ds = xr.Dataset(
        data, coords={"surface": names, "species": species, "time": ("time", time, {"units": "s"})}
    )
    ds.attrs.update(_attrs(result))
    return ds
