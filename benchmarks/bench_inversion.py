"""Per-pixel inversion: pixels per second of the engine, against a baseline in
the same run: scipy.optimize.least_squares on the same fast forward model
(the per-scene table, evaluated in numpy from its exported coefficients).

Figures (HITRAN tables, 17 mK noise, T_amb 20 C, backgrounds 15 K colder):
  * single channel (GF320, CH4, temperature assumed, sigma given): the
    engine's Newton path. Target >= 1,000,000 px/s.
  * four channels (fast-m150), 4 parameters (x_CH4, x_CO2, T_peak free;
    sigma with a prior): cold starts (coarse lookup + a full solve from every
    candidate) and warm starts (the neighbouring pixel of an image row).
    Target >= 20,000 px/s.
  * four channels, temperature known (fractions free).
Also: the scene table's build time and its error against the binned model.

Set QOGI_BENCH_QUICK=1 for a shorter run."""

import os
import pathlib
import time

import numpy as np
from scipy.optimize import least_squares

import qogi
from qogi import _engine
from qogi.measure.inversion import fixed, free, prior

HITRAN = (
    pathlib.Path(
        os.environ.get("QOGI_SHARED_DIR", pathlib.Path(__file__).resolve().parents[2] / "shared")
    )
    / "hitran"
)
QUICK = os.environ.get("QOGI_BENCH_QUICK") == "1"
T_AMB, T_BG = 293.15, 278.15
C1, C2 = 1.191042972e-8, 1.438776877


# --- the baseline's forward model: the scene table in numpy ------------------


def _weights(t, n, hold_below=False):
    """Cubic B-spline weights (4) and first coefficient index at grid coordinate t."""
    if n == 1:
        return 0, np.array([1.0])

    def basis(f):
        g = 1 - f
        w = np.array([g**3, 3 * f**3 - 6 * f**2 + 4, -3 * f**3 + 3 * f**2 + 3 * f + 1, f**3]) / 6
        dw = np.array([-g * g, 3 * f * f - 4 * f, -3 * f * f + 2 * f + 1, f * f]) / 2
        return w, dw

    if 0 <= t <= n - 1:
        i = min(int(np.floor(t)), n - 2)
        return i, basis(t - i)[0]
    low = t < 0
    i, edge = (0, 0.0) if low else (n - 2, n - 1.0)
    w, dw = basis(0.0 if low else 1.0)
    return i, (w if (low and hold_below) else w + (t - edge) * dw)


def _planck(nu, t):
    return C1 * nu**3 / np.expm1(C2 * nu / t)


class NumpyTable:
    def __init__(self, table, nc, ns):
        self.nc, self.ns = nc, ns
        self.parts = {
            (c, s): table.export(c, s)
            for c in range(nc)
            for s in range(ns)
            if table.has_table(c, s)
        }

    @staticmethod
    def _phi(p, t):
        nb = p["psi_coefficients"].shape[0] - 2
        i, w = _weights((t - p["background_t0"]) / p["background_step"], nb)
        return w @ p["psi_coefficients"][i : i + 4] * _planck(p["nu_ref_cm1"], t)

    def contrast(self, x, tp, sigma, tbg):
        out = np.zeros(self.nc)
        for (c, s), p in self.parts.items():
            u = x[s] * sigma
            lu = np.log(u) if u > np.exp(p["log_u0"]) else p["log_u0"]
            iu, wu = _weights((lu - p["log_u0"]) / p["log_u_step"], p["num_u"], hold_below=True)
            ix, wx = _weights(x[s] * (p["num_x"] - 1), p["num_x"])
            it, wt = _weights((tp - p["t0"]) / p["t_step"], p["num_t"])
            blk = p["coefficients"][it : it + 4, ix : ix + len(wx), iu : iu + 4]
            v = np.einsum("a,b,c,abcr->r", wt, wx, wu, blk)
            dphi = self._phi(p, tp) - self._phi(p, tbg[c])
            out[c] += u * (v[0] + dphi @ v[1:])
        return out


def scipy_invert(nt, y, noise, tbg, x0, bounds, sigma_prior=None, fixed_t=None, fixed_sigma=None):
    """One pixel with scipy.optimize.least_squares (trust-region reflective,
    2-point Jacobian); parameters (x..., [T], [sigma])."""
    ns = nt.ns

    def unpack(p):
        x = p[:ns]
        t = fixed_t if fixed_t is not None else p[ns]
        s = fixed_sigma if fixed_sigma is not None else p[-1]
        return x, t, s

    def resid(p):
        x, t, s = unpack(p)
        r = (nt.contrast(x, t, s, tbg) - y) / noise
        if sigma_prior is not None:
            r = np.append(r, (s - sigma_prior[0]) / sigma_prior[1])
        return r

    sol = least_squares(resid, x0, bounds=bounds, x_scale="jac")
    return sol.x, sol.nfev


def timed(fn):
    """(result, wall seconds, process CPU seconds): on a shared machine the CPU
    time shows what the run got; px per CPU-second x cores is the rate on idle
    cores."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t0, time.process_time() - c0


def image(model, table, h, w, seed):
    """A smooth plume image (channels, H, W): 50/50 CH4/CO2, peak fraction
    falling with height and across, temperature decaying from 80 C, sigma
    growing with height; plus 17 mK noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    height = 1 + yy[::-1] / h
    sg = 0.01 * height
    xt = 0.3 / height**2 * np.exp(-0.5 * ((xx - w / 2) / (0.15 * w * height)) ** 2)
    tp = T_AMB + 60.0 / height**2
    n = h * w
    x = np.stack([xt.ravel() / 2, xt.ravel() / 2], 1)
    con, _ = table.contrast(x, tp.ravel(), sg.ravel(), np.full((n, 4), T_BG))
    bg = np.array([c.band_radiance(T_BG) for c in model.channels])
    noise = np.array(qogi.netd_radiance_sigma(model.channels, 0.017, T_BG))
    rad = con + bg + rng.standard_normal((n, 4)) * noise
    return rad.T.reshape(4, h, w), sg, tp, bg, noise


def main():
    threads = os.cpu_count()
    m150, gf = qogi.camera_preset("fast-m150"), qogi.camera_preset("gf320")
    ll = {"CH4": HITRAN / "CH4.par", "CO2": HITRAN / "CO2.par"}
    model = qogi.ForwardModel(m150, ["CH4", "CO2"], line_lists=ll)
    model.fast  # noqa: B018  (build the binned model outside the timings)

    print(f"load average at start: {os.getloadavg()[0]:.1f} on {threads} cores")
    # --- single channel ------------------------------------------------------
    single = qogi.ForwardModel(gf, ["CH4"], line_lists={"CH4": ll["CH4"]})
    t0 = time.perf_counter()
    inv1 = qogi.Inversion(single, T_AMB, netd_K=0.015, sigma_m=0.03)
    print(f"single-channel table built in {time.perf_counter() - t0:.1f} s")
    n1 = 200_000 if QUICK else 1_000_000
    rng = np.random.default_rng(1)
    x = 10 ** rng.uniform(-3.5, -0.5, n1)
    lum = single.band_radiance({"CH4": x[:2000]}, T_AMB, 0.03, T_AMB, T_BG)[:, 0]
    noise1 = inv1.channel_noise(T_BG)
    rad1 = np.tile(lum, n1 // 2000)[None] + rng.standard_normal((1, n1)) * noise1[0]
    bg1 = np.full((1, n1), T_BG)
    inv1.invert(rad1[:, :1000], background_temperature_K=bg1[:, :1000])  # warm-up
    r1, wall, cpu = timed(lambda: inv1.invert(rad1, background_temperature_K=bg1))
    eng1, eng1_cpu = n1 / wall, n1 / cpu
    nt1 = NumpyTable(inv1.table, 1, 1)
    ns1 = 30 if QUICK else 100
    t0 = time.perf_counter()
    agree = []
    for i in range(ns1):
        y = rad1[0, i] - gf.channels[0].band_radiance(T_BG)
        p, _ = scipy_invert(
            nt1,
            np.array([y]),
            noise1,
            np.array([T_BG]),
            np.array([1e-3]),
            ([0.0], [1.0]),
            fixed_t=T_AMB,
            fixed_sigma=0.03,
        )
        if r1.status[i] == 0:
            agree.append(abs(p[0] / r1.peak_fraction["CH4"][i] - 1))
    base1 = ns1 / (time.perf_counter() - t0)
    print(
        f"single channel (GF320, CH4, Newton on the table), {n1} px on {threads} threads: "
        f"{eng1:,.0f} px/s ({eng1_cpu:,.0f} px per CPU-second); scipy least_squares on the "
        f"numpy table: {base1:,.0f} px/s; "
        f"ratio {eng1 / base1:,.0f}x (target >= 1,000,000 px/s); statuses {r1.counts()}; "
        f"scipy vs engine median |dx/x| {np.median(agree):.1e}"
    )

    # --- four channels -------------------------------------------------------
    t0 = time.perf_counter()
    # The free four-channel fit: T_peak free in [T_amb - 10, T_amb + 90] K,
    # the depth with a 1.5 +- 1 cm prior.
    free4 = dict(netd_K=0.017, temperature=free(T_AMB - 10, T_AMB + 90), sigma_m=prior(0.015, 0.01))
    inv4 = qogi.Inversion(model, T_AMB, **free4)
    tab = inv4.table
    print(
        f"four-channel table: built in {time.perf_counter() - t0:.1f} s "
        f"(grid {tab.grid_shape}, {tab.num_tabulated_bins} bins, {tab.memory_bytes / 1e6:.1f} MB)"
    )
    err = _engine.measure_table_error(tab, 40 if QUICK else 150, 2)
    print(
        f"  table vs binned model: max {err['max_relative_error']:.1e}, rms "
        f"{err['rms_relative_error']:.1e} of the contrast (floor 1 mK)"
    )
    h, w = (40, 60) if QUICK else (120, 160)
    rad, sg, tp, bg, noise = image(model, tab, h, w, 2)
    n4 = h * w
    inv4.invert(rad[:, :2, :], background_temperature_K=T_BG, sigma_m=sg[:2])  # warm-up
    cold, wall, cpu = timed(lambda: inv4.invert(rad, background_temperature_K=T_BG))
    eng_cold, cold_cpu = n4 / wall, n4 / cpu
    warm_inv = qogi.Inversion(model, T_AMB, initial_guess="neighbour", **free4)
    warm, wall, cpu = timed(lambda: warm_inv.invert(rad, background_temperature_K=T_BG))
    eng_warm, warm_cpu = n4 / wall, n4 / cpu
    known = qogi.Inversion(
        model,
        T_AMB,
        netd_K=0.017,
        temperature=fixed(330.0),
        temperature_range_K=(T_AMB - 10, T_AMB + 90),
        sigma_m=0.015,
    )
    kn, wall, cpu = timed(
        lambda: known.invert(rad, background_temperature_K=T_BG, sigma_m=sg, peak_temperature_K=tp)
    )
    eng_known, known_cpu = n4 / wall, n4 / cpu
    nt4 = NumpyTable(tab, 4, 2)
    flat = rad.reshape(4, -1)
    pick = np.flatnonzero(cold.valid.ravel())[:: max(1, n4 // (20 if QUICK else 60))]
    t0 = time.perf_counter()
    diffs = []
    for i in pick:
        y = flat[:, i] - bg
        p, _ = scipy_invert(
            nt4,
            y,
            noise,
            np.full(4, T_BG),
            np.array([1e-3, 1e-3, T_AMB + 20, 0.015]),
            ([0, 0, T_AMB - 10, 1e-4], [1, 1, T_AMB + 90, 2.0]),
            sigma_prior=(0.015, 0.01),
        )
        c_eng = cold.parameters.reshape(-1, 4)[i]
        diffs.append(abs(p[0] * p[3] / (c_eng[0] * c_eng[3]) - 1))
    base4 = len(pick) / (time.perf_counter() - t0)
    print(
        f"four channels, 4 parameters (x_CH4, x_CO2, T free, sigma prior), {n4} px image "
        f"on {threads} threads:\n  cold starts {eng_cold:,.0f} px/s ({cold_cpu:,.0f} per "
        f"CPU-s; {eng_cold / base4:,.0f}x scipy); neighbour warm starts {eng_warm:,.0f} px/s "
        f"({warm_cpu:,.0f} per CPU-s; {eng_warm / base4:,.0f}x); "
        f"scipy least_squares (one start) on the numpy table {base4:,.1f} px/s "
        f"(target >= 20,000 px/s)\n  statuses cold {cold.counts()}, warm {warm.counts()}; "
        f"ambiguous (two minima) {int(np.sum(cold.flags & 1))}; scipy (one start) vs engine "
        f"median |d(x sigma)/(x sigma)| {np.median(diffs):.1e}"
    )
    print(
        f"four channels, temperature known (fractions free): {eng_known:,.0f} px/s "
        f"({known_cpu:,.0f} per CPU-s; {eng_known / base4:,.0f}x scipy); statuses {kn.counts()}"
    )


if __name__ == "__main__":
    main()
