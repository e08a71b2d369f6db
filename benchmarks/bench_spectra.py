"""Spectroscopy speed: qogi vs HAPI 1.3 on the issue's case, and table builds.

1. CH4, 2800-3200 cm-1 at 0.01 cm-1 (40,001 points), the 25,126-line list,
   296 K, 1 atm, HAPI's default settings (50-half-width wings, line shift,
   TIPS-2025), gas as a trace in air: HAPI's ``absorptionCoefficient_Voigt``
   (tables loaded beforehand with ``db_begin``) against
   ``qogi.cross_section(..., cutoff="hapi")`` on the loaded line list; the
   ratio, and the agreement of the two results.
2. The tables the forward model asks for (0.01 cm-1, 200-800 K every 10 K,
   1 atm, 25 cm-1 wings): build time (61 spectra), as a fraction of HAPI's
   time for the single spectrum of part 1, and the interpolation error at
   off-grid temperatures against direct computation.

HAPI is optional (``pip install hitran-api``; ``make bench`` installs it):
without it the comparison is skipped with a message.
"""

from __future__ import annotations

import contextlib
import io
import os
import pathlib
import shutil
import tempfile
import time

import numpy as np
from _timing import best_time

import qogi
from qogi.physics import spectra

SHARED = pathlib.Path(
    os.environ.get("QOGI_SHARED_DIR", pathlib.Path(__file__).resolve().parents[2] / "shared")
)
HITRAN = SHARED / "hitran"


def hapi_case(nu_range, step, temperature):
    """(seconds, nu, sigma) of HAPI's run, or None when HAPI is missing."""
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import hapi
    except ImportError:
        print(
            "HAPI (hitran-api) is not installed: skipping the HAPI comparison "
            "(`.venv/bin/pip install hitran-api`, or `make bench`)."
        )
        return None
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copy(HITRAN / "CH4.par", tmp)
        with contextlib.redirect_stdout(io.StringIO()):
            hapi.db_begin(tmp)
            t0 = time.perf_counter()
            nu, sigma = hapi.absorptionCoefficient_Voigt(
                SourceTables="CH4",
                WavenumberRange=nu_range,
                WavenumberStep=step,
                Environment={"T": temperature, "p": 1.0},
                Diluent={"air": 1.0},
                HITRAN_units=True,
            )
            dt = time.perf_counter() - t0
    return dt, np.asarray(nu), np.asarray(sigma), hapi.HAPI_VERSION


def main() -> None:
    threads = qogi._engine.resolve_threads(0)
    print(f"qogi {qogi.__version__}, {threads} threads")

    # --- 1. HAPI vs qogi ---------------------------------------------------
    rng, step, temp = (2800.0, 3200.0), 0.01, 296.0
    nu0, dnu, n = qogi._engine.grid_from_range(*rng, step)
    nu = nu0 + dnu * np.arange(n)
    spectra._loaded.clear()
    t0 = time.perf_counter()
    lines = qogi.load_line_list("CH4", HITRAN / "CH4.par")
    t_read = time.perf_counter() - t0
    sigma = qogi.cross_section("CH4", nu, temp, line_list=lines, cutoff="hapi")
    t_qogi = best_time(
        lambda: qogi.cross_section("CH4", nu, temp, line_list=lines, cutoff="hapi"), 20
    )
    print(
        f"\nCH4 {rng[0]:g}-{rng[1]:g} cm-1 step {step} ({n} points), {len(lines)} lines, "
        f"{temp:g} K, 1 atm, HAPI default wings"
    )
    print(f"  qogi cross_section:        {t_qogi * 1e3:8.1f} ms (best of 20)")
    print(f"  qogi reading CH4.par:      {t_read * 1e3:8.1f} ms (once)")
    hapi = hapi_case(rng, step, temp)
    t_hapi = None
    if hapi is not None:
        t_hapi, hnu, hsigma, version = hapi
        print(f"  HAPI {version} absorptionCoefficient_Voigt: {t_hapi * 1e3:8.1f} ms")
        print(
            f"  speed-up qogi vs HAPI:     {t_hapi / t_qogi:8.0f}x  "
            f"(incl. reading the file: {t_hapi / (t_qogi + t_read):.0f}x)"
        )
        strong = hsigma > 0.01 * hsigma.max()
        print(
            f"  agreement: max |rel diff| where sigma > 1% of max = "
            f"{np.max(np.abs(sigma[strong] / hsigma[strong] - 1)):.1e}, "
            f"integral {np.sum(sigma) / np.sum(hsigma) - 1:+.1e}"
        )

    # --- 2. Forward-model tables --------------------------------------------
    print(
        "\nTables, 0.01 cm-1, 200-800 K every 10 K (61 temperatures), 1 atm, "
        f"{spectra.DEFAULT_TABLE_CUTOFF_CM1:g} cm-1 wings:"
    )
    cases = [
        ("CH4", 2830.0, 3250.0, 0.0),
        ("CH4", 2830.0, 3250.0, 1.0),
        ("CO2", 2100.0, 2300.0, 0.0),
        ("H2O", 2830.0, 3250.0, 0.0),
    ]
    for species, lo, hi, x in cases:
        t0 = time.perf_counter()
        table = qogi.cross_section_table(species, lo, hi, self_fraction=x, cache=False)
        t_build = time.perf_counter() - t0
        nlines = table.metadata["lines"]
        worst = 0.0
        for t in (205.0, 296.0, 333.3, 517.0, 795.0):
            direct = qogi.cross_section(
                species, table.nu_cm1, t, self_fraction=x, cutoff=spectra.DEFAULT_TABLE_CUTOFF_CM1
            )
            strong = direct > 0.01 * direct.max()
            worst = max(
                worst, float(np.max(np.abs(table.interpolate(t)[strong] / direct[strong] - 1)))
            )
        line = (
            f"  {species} {lo:g}-{hi:g} cm-1, self fraction {x:g} ({nlines} lines, "
            f"{table.nu_cm1.size} points): build {t_build:6.2f} s, "
            f"interpolation error {worst:.1e} (205-795 K, sigma > 1% of max)"
        )
        if t_hapi is not None:
            line += f"; {t_build / t_hapi:.2f} x HAPI's one spectrum above"
        print(line)


if __name__ == "__main__":
    main()
