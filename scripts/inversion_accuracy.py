"""Accuracy of the inversion with the gas temperature known, with the
composition known and the temperature free, and with everything free: the
round trip of docs/inversion.md through the exact model (HITRAN tables,
fast-m150, 17 mK NETD), 12 plumes x 100 noise draws.

    .venv/bin/python scripts/inversion_accuracy.py
"""

import time

import numpy as np

import qogi
from qogi.measure.inversion import fixed, free, tied

HITRAN = qogi.physics.spectra.bundled_hitran_dir()
T_AMB = 293.15


def main():
    cam = qogi.camera_preset("fast-m150")
    model = qogi.ForwardModel(
        cam,
        ["CH4", "CO2"],
        line_lists={"CH4": HITRAN / "CH4.par.gz", "CO2": HITRAN / "CO2.par.gz"},
        exact_options=qogi._engine.ExactModelOptions(num_nodes=101),
    )
    rng = np.random.default_rng(5)
    m, draws = 12, 100
    tp = rng.permutation(np.linspace(303.15, 363.15, m))
    tbg = T_AMB - rng.uniform(10, 20, m)
    total = rng.permutation(np.geomspace(2e-3, 0.4, m))
    x = np.stack([total / 2, total / 2], 1)
    sg = rng.uniform(0.02, 0.1, m)
    t0 = time.time()
    exact = model.band_radiance(x, tp, sg, T_AMB, tbg[:, None].repeat(4, 1), exact=True)
    print(f"{m} exact-model plumes in {time.time() - t0:.0f} s, {draws} noise draws each")
    noise = np.stack([qogi.netd_radiance_sigma(cam, 0.017, t) for t in tbg])
    rad = np.repeat(exact, draws, 0) + rng.standard_normal((m * draws, 4)) * np.repeat(
        noise, draws, 0
    )
    TP, TB, SG = (np.repeat(a, draws) for a in (tp, tbg, sg))
    truth = model.column_density(np.repeat(x, draws, 0), TP, SG, T_AMB)
    bg = np.repeat(TB[None], 4, 0)
    cases = [
        (
            "T known, fractions free",
            dict(temperature=fixed(330.0), temperature_range_K=(T_AMB - 10, T_AMB + 90)),
            TP,
        ),
        (
            "composition known (50/50), T free",
            dict(
                temperature=free(T_AMB - 10, T_AMB + 90),
                fractions={"CH4": free(), "CO2": tied("CH4", 1.0)},
            ),
            None,
        ),
        ("x_CH4, x_CO2, T free", dict(temperature=free(T_AMB - 10, T_AMB + 90)), None),
    ]
    for name, kw, t_given in cases:
        inv = qogi.Inversion(model, T_AMB, netd_K=0.017, sigma_m=0.05, **kw)
        t0 = time.time()
        r = inv.invert(rad.T, background_temperature_K=bg, sigma_m=SG, peak_temperature_K=t_given)
        print(
            f"{name}: {time.time() - t0:.2f} s, {r.counts()}, "
            f"ambiguous {int(np.sum(r.flags & 1))}, median condition number "
            f"{np.median(r.condition_number[r.valid]):.0f}"
        )
        ok = r.valid
        for s in ("CH4", "CO2"):
            e = r.column_density[s] - truth[s]
            z = e[ok] / r.column_density_sigma[s][ok]
            robust = 1.4826 * np.median(np.abs(z - np.median(z)))
            print(
                f"  {s}: median |error| {100 * np.median(np.abs(e[ok] / truth[s][ok])):.2f} %, "
                f"z std {z.std():.2f} (robust {robust:.2f}), mean {z.mean():+.2f}, "
                f"|z| > 4: {100 * np.mean(np.abs(z) > 4):.1f} %"
            )
        if t_given is None:
            print(
                f"  T error median {np.median(np.abs(r.peak_temperature_K - TP)[ok]):.1f} K, "
                f"reported sigma_T median {np.median(r.peak_temperature_sigma_K[ok]):.1f} K"
            )


if __name__ == "__main__":
    main()
