"""Computes the HAPI reference cross-sections that qogi's agreement tests use.

HAPI 1.3 (R.V. Kochanov et al., "HITRAN Application Programming Interface
(HAPI)", JQSRT 177 (2016) 15-30; ``pip install hitran-api==1.3.0.0``)
``absorptionCoefficient_Voigt`` with its defaults (50-half-width wings,
pressure shift on, TIPS-2025 partition sums, no intensity threshold) and
``Diluent={'air': 1.0}``, ``HITRAN_units=True`` (cm2/molecule), p = 1 atm,
0.01 cm-1 grid, on the line lists qogi ships (python/qogi/data/hitran; the
records are those of the HITRAN files their MANIFEST.json names):

* CH4.par, 2850-3200 cm-1 at 250, 296 and 350 K;
* CO2.par, 2100-2300 cm-1 (the span the list covers) at 296 and 363 K;
* H2O.par, 3600-3900 cm-1 at 296 K.

Writes ``tests/data/hapi_reference.npz`` (float32 sigma per case, its grid,
the settings and the SHA-256 of each line file). Run from the repository::

    .venv/bin/pip install hitran-api==1.3.0.0
    .venv/bin/python scripts/make_hapi_references.py [--line-lists FOLDER]

HAPI's ``db_begin`` writes .header files beside the tables, so the line files
are copied into a scratch folder first.
"""

from __future__ import annotations

import argparse
import contextlib
import gzip
import hashlib
import io
import json
import pathlib
import tempfile
import time

import numpy as np

REPO = pathlib.Path(__file__).resolve().parents[1]
OUT = REPO / "tests" / "data" / "hapi_reference.npz"

CASES = [
    ("CH4", "CH4.par", 2850.0, 3200.0, 250.0),
    ("CH4", "CH4.par", 2850.0, 3200.0, 296.0),
    ("CH4", "CH4.par", 2850.0, 3200.0, 350.0),
    ("CO2", "CO2.par", 2100.0, 2300.0, 296.0),
    ("CO2", "CO2.par", 2100.0, 2300.0, 363.0),
    ("H2O", "H2O.par", 3600.0, 3900.0, 296.0),
]
STEP = 0.01


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--line-lists",
        type=pathlib.Path,
        default=REPO / "python" / "qogi" / "data" / "hitran",
        help="folder of NAME.par.gz (default: the ones qogi ships)",
    )
    args = ap.parse_args()
    with contextlib.redirect_stdout(io.StringIO()):
        import hapi
    if hapi.HAPI_VERSION != "1.3.0.0":
        raise SystemExit(f"expected HAPI 1.3.0.0, found {hapi.HAPI_VERSION}")
    src = args.line_lists
    arrays: dict[str, np.ndarray] = {}
    meta = {
        "hapi_version": hapi.HAPI_VERSION,
        "function": "absorptionCoefficient_Voigt",
        "Diluent": {"air": 1.0},
        "HITRAN_units": True,
        "pressure_atm": 1.0,
        "WavenumberStep": STEP,
        "defaults": "WavenumberWingHW=50, LineShift=True, "
        "partitionFunction=PYTIPS (TIPS-2025), IntensityThreshold=0",
        "cases": [],
        "line_files": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        for name in sorted({c[1] for c in CASES}):
            records = gzip.decompress((src / (name + ".gz")).read_bytes())
            (pathlib.Path(tmp) / name).write_bytes(records)
            meta["line_files"][name] = hashlib.sha256(records).hexdigest()
        with contextlib.redirect_stdout(io.StringIO()):
            hapi.db_begin(tmp)
        for species, fname, lo, hi, temp in CASES:
            table = fname.split(".")[0]
            t0 = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()):
                nu, sigma = hapi.absorptionCoefficient_Voigt(
                    SourceTables=table,
                    WavenumberRange=(lo, hi),
                    WavenumberStep=STEP,
                    Environment={"T": temp, "p": 1.0},
                    Diluent={"air": 1.0},
                    HITRAN_units=True,
                )
            dt = time.perf_counter() - t0
            key = f"{species}_{int(lo)}_{int(hi)}_{int(temp)}K"
            arrays[key] = np.asarray(sigma, dtype=np.float32)
            meta["cases"].append(
                {
                    "key": key,
                    "species": species,
                    "line_file": fname,
                    "nu0_cm1": float(nu[0]),
                    "step_cm1": STEP,
                    "size": int(len(nu)),
                    "nu_last_cm1": float(nu[-1]),
                    "temperature_K": temp,
                    "hapi_seconds": round(dt, 2),
                }
            )
            print(f"{key}: {len(nu)} points, {dt:.1f} s")
    np.savez_compressed(OUT, meta=np.array(json.dumps(meta)), **arrays)
    print(f"wrote {OUT} ({OUT.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
