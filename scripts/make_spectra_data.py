"""Regenerates the spectroscopic data tables shipped with qogi's spectra module.

Writes, under ``cpp/engine/spectra/data/``:

``molecules.csv``
    HITRAN molecule codes and formulas (``molecule_id,formula``).
``isotopologues.csv``
    For the molecules qogi ships partition sums for: HITRAN molecule code,
    local isotopologue number, global isotopologue id (the one HITRANonline's
    API takes), formula, natural abundance and molar mass [g/mol], as tabulated
    by HITRAN (the ``ISO`` table of HAPI).
``tips_2025.csv``
    Total internal partition sums Q(T) of those isotopologues on the TIPS
    temperature grid (``molecule_id,local_id,temperature_K,q``): TIPS-2025,
    Gamache et al., JQSRT 345 (2025) 109568, doi:10.1016/j.jqsrt.2025.109568,
    the default partition sums of HAPI 1.3 (``partitionSum(..., version=2025)``).
    TIPS-2021 (Gamache et al., JQSRT 271 (2021) 107713) differs from it by
    less than 1e-6 relative for these isotopologues at 200-1000 K.

The values are copied from the ``hitran-api`` package (HAPI 1.3.0.0; R.V.
Kochanov et al., JQSRT 177 (2016) 15-30), which must be installed::

    .venv/bin/pip install hitran-api==1.3.0.0
    .venv/bin/python scripts/make_spectra_data.py

The files are inputs of the build (embedded into the library by CMake), so
they are committed; rerun this script only to change the molecule set or the
TIPS edition.
"""

from __future__ import annotations

import contextlib
import io
import pathlib

# HITRAN molecule codes to ship partition sums for: H2O, CO2, N2O, CO, CH4
# (the gases a MWIR gas camera sees, and the interferers in their bands).
MOLECULES = (1, 2, 4, 5, 6)

OUT = pathlib.Path(__file__).resolve().parents[1] / "cpp" / "engine" / "spectra" / "data"


@contextlib.contextmanager
def _table(name: str, comment: str, columns: str):
    """A CSV file of OUT open for writing, its comment and column lines written."""
    with open(OUT / name, "w") as fh:
        fh.write(f"# {comment}\n")
        fh.write(f"{columns}\n")
        yield fh


def main() -> None:
    with contextlib.redirect_stdout(io.StringIO()):  # HAPI prints a banner
        import hapi
    if hapi.HAPI_VERSION != "1.3.0.0":
        raise SystemExit(f"expected HAPI 1.3.0.0, found {hapi.HAPI_VERSION}")
    iso = hapi.ISO
    idx = hapi.ISO_INDEX
    OUT.mkdir(parents=True, exist_ok=True)

    names = {}
    for (m, _i), row in iso.items():
        names[m] = row[idx["mol_name"]]
    with _table(
        "molecules.csv",
        "HITRAN molecule codes (from HAPI 1.3.0.0's ISO table)",
        "molecule_id,formula",
    ) as fh:
        for m in sorted(names):
            fh.write(f"{m},{names[m]}\n")

    keys = sorted(k for k in iso if k[0] in MOLECULES)
    with _table(
        "isotopologues.csv",
        "HITRAN isotopologues: natural abundance and molar mass "
        "(HITRAN, via HAPI 1.3.0.0's ISO table)",
        "molecule_id,local_id,global_id,formula,abundance,molar_mass_g_mol",
    ) as fh:
        for m, i in keys:
            row = iso[(m, i)]
            fh.write(
                f"{m},{i},{row[idx['id']]},{row[idx['iso_name']]},"
                f"{float(row[idx['abundance']])!r},{float(row[idx['mass']])!r}\n"
            )

    with _table(
        "tips_2025.csv",
        "Total internal partition sums Q(T), TIPS-2025 (Gamache et al., "
        "JQSRT 345 (2025) 109568), as shipped in HAPI 1.3.0.0",
        "molecule_id,local_id,temperature_K,q",
    ) as fh:
        for m, i in keys:
            temps = hapi.TIPS_2025_ISOT_HASH[(m, i)]
            qs = hapi.TIPS_2025_ISOQ_HASH[(m, i)]
            if len(temps) != len(qs):
                raise SystemExit(f"TIPS table of ({m},{i}) is inconsistent")
            for t, q in zip(temps, qs):
                fh.write(f"{m},{i},{float(t)!r},{float(q)!r}\n")
    print(f"wrote {len(names)} molecules, {len(keys)} isotopologues to {OUT}")


if __name__ == "__main__":
    main()
