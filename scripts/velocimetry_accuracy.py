"""Accuracy table of every velocimetry method on scenes with exact motion.

Prints the tables of docs/velocimetry.md: mean end-point error [px] on moving
textures, on column-density blobs advected by the continuity equation, and
the velocity read in the featureless base of a steady plume column. Seeded;
a few seconds.

Usage: .venv/bin/python scripts/velocimetry_accuracy.py
"""

from __future__ import annotations

import numpy as np

import qogi
from qogi.measure import velocimetry as vel

METHODS = list(vel.METHODS)


def texture(seed, n=64, lam=(6.0, 24.0)):
    rng = np.random.default_rng(seed)
    lamb = rng.uniform(*lam, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    kx, ky = 2 * np.pi / lamb * np.cos(ang), 2 * np.pi / lamb * np.sin(ang)
    ph = rng.uniform(0, 2 * np.pi, n)

    def t(x, y):
        out = np.zeros(np.broadcast(x, y).shape)
        for i in range(n):
            out += np.cos(kx[i] * x + ky[i] * y + ph[i])
        return out * np.sqrt(2.0 / n)

    return t


def inverse(w, X, Y, iters=30):
    """phi^-1 for phi(x) = x + w(x), by fixed-point iteration x = X - w(x)."""
    x, y = X.copy(), Y.copy()
    for _ in range(iters):
        u, v = w(x, y)
        x, y = X - u, Y - v
    return x, y


def jacobian(w, x, y, h=1e-4):
    ux1, vx1 = w(x + h, y)
    ux0, vx0 = w(x - h, y)
    uy1, vy1 = w(x, y + h)
    uy0, vy0 = w(x, y - h)
    a = 1 + (ux1 - ux0) / (2 * h)
    b = (uy1 - uy0) / (2 * h)
    c = (vx1 - vx0) / (2 * h)
    d = 1 + (vy1 - vy0) / (2 * h)
    return a * d - b * c


def noisy(a, b, level, scale, seed):
    rng = np.random.default_rng(seed)
    return (a + rng.normal(0, level * scale, a.shape), b + rng.normal(0, level * scale, b.shape))


def texture_scene(w, H=160, W=192):
    t = texture(7)
    y, x = np.mgrid[0:H, 0:W].astype(float)
    a = np.exp(0.4 * t(x, y))
    x0, y0 = inverse(w, x, y)
    b = np.exp(0.4 * t(x0, y0))
    a, b = noisy(a, b, 0.01, a.std(), 3)
    tu, tv = w(x, y)
    region = np.zeros((H, W), bool)
    region[16:-16, 16:-16] = True
    return a, b, tu, tv, region


def density_scene(w, H=160, W=192, contrast=0.2):
    t = texture(7)
    y, x = np.mgrid[0:H, 0:W].astype(float)
    cx, cy = W / 2, H / 2

    def rho(xx, yy):
        env = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * 50.0**2))
        return env * np.exp(contrast * t(xx, yy))

    a = rho(x, y)
    x0, y0 = inverse(w, x, y)
    b = rho(x0, y0) / jacobian(w, x0, y0)
    a, b = noisy(a, b, 0.005, a.max(), 3)
    tu, tv = w(x, y)
    return a, b, tu, tv, (x - cx) ** 2 + (y - cy) ** 2 <= 60**2


def epe(f, tu, tv, region):
    ok = region & f.valid
    return float(np.hypot(f.u - tu, f.v - tv)[ok].mean())


def table(title, scenes):
    print(f"\n{title}")
    print(f"| scene | {' | '.join(METHODS)} |")
    print("|---" * (len(METHODS) + 1) + "|")
    for name, (a, b, tu, tv, region) in scenes.items():
        errs = [epe(qogi.optical_flow(a, b, method=m), tu, tv, region) for m in METHODS]
        print(f"| {name} | " + " | ".join(f"{e:.3f}" for e in errs) + " |")


def steady_column(
    t0, H=192, W=128, exit_y=180.0, cx=64.0, sx=12.0, u0=3.0, k=0.008, age=25.0, contrast=0.3
):
    """Frames t0, t0 + 1 of the steady decelerating column of the C++ tests."""
    t = texture(11)
    y, x = np.mgrid[0:H, 0:W].astype(float)
    z = exit_y - y

    def rho(time):
        zz = np.clip(z, 0, None)
        tau = -np.log(1 - k * zz / u0) / k
        born = time - tau
        wgt = np.clip((-born - age) / 4.0, 0, 1)
        m = 1 + contrast * wgt * t(x, born * u0)
        e = np.exp(-((x - cx) ** 2) / (2 * sx**2))
        return np.where(z >= 0, e * u0 / (u0 - k * zz) * m, 0.0)

    a, b = rho(t0), rho(t0 + 1)
    a, b = noisy(a, b, 0.005, a.max(), 5 + int(t0))
    tv = np.where(z >= 0, -(u0 / k - z) * (1 - np.exp(-k)), 0.0)
    return a, b, tv


def main():
    def translation(dx, dy):
        return lambda x, y: (np.full_like(x, dx), np.full_like(y, dy))

    def rotation(th, cx, cy):
        c, s = np.cos(th), np.sin(th)
        return lambda x, y: (
            c * (x - cx) - s * (y - cy) - (x - cx),
            s * (x - cx) + c * (y - cy) - (y - cy),
        )

    def jet(peak, cy, sig):
        return lambda x, y: (peak * np.exp(-((y - cy) ** 2) / (2 * sig**2)), 0 * y)

    def spreading(r, cx, cy):
        return lambda x, y: (r * (x - cx), r * (y - cy))

    def source(r, cx, cy, sig, dx, dy):
        def w(x, y):
            g = np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sig**2))
            return dx + r * (x - cx) * g, dy + r * (y - cy) * g

        return w

    def vortex(peak, cx, cy, sig, dx, dy):
        def w(x, y):
            g = np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * sig**2))
            return dx - peak * (y - cy) / sig * g, dy + peak * (x - cx) / sig * g

        return w

    table(
        "Moving textures, 192 x 160, 1 % noise, mean EPE [px] over the interior:",
        {
            "translation 1 px": texture_scene(translation(0.8, -0.6)),
            "translation 3 px": texture_scene(translation(2.4, 1.8)),
            "rotation (3 px at corners)": texture_scene(rotation(3 / 125, 96, 80)),
            "jet shear (2.5 px peak)": texture_scene(jet(2.5, 80, 25)),
        },
    )
    table(
        "Continuity-advected blobs (texture +-20 %, 0.5 % noise), mean EPE [px] "
        "within 60 px of the centre:",
        {
            "vortex + drift (div-free)": density_scene(vortex(1.5, 96, 80, 30, 1.0, 0.5)),
            "spreading (div 0.03 /frame)": density_scene(spreading(0.015, 96, 80)),
            "source + drift": density_scene(source(0.05, 96, 80, 30, 1.5, -0.8)),
        },
    )

    print("\nSteady column, featureless base (5-55 px above the exit, within 1 sigma):")
    print(
        "mean v [px/frame] read in the base; truth first. 'fluid seq' = 6 warm-started "
        "pairs with the exit as source_mask."
    )
    a, b, tv = steady_column(0.0)
    base = np.zeros(a.shape, bool)
    base[125:175, 52:77] = True
    mask = vel.plume_mask(a)
    row = {"truth": tv[base].mean()}
    for m in METHODS:
        row[m] = qogi.optical_flow(a, b, method=m, mask=mask).v[base].mean()
    src = np.zeros(a.shape, bool)
    src[179:182, :] = True
    est = vel.FlowEstimator("fluid", source_mask=src)
    f = None
    for t0 in range(6):
        a, b, tv = steady_column(float(t0))
        f = est.calc(a, b, mask=vel.plume_mask(a), flow=f)
    row["fluid seq"] = f.v[base].mean()
    print("| " + " | ".join(row) + " |")
    print("|---" * len(row) + "|")
    print("| " + " | ".join(f"{v:.2f}" for v in row.values()) + " |")


if __name__ == "__main__":
    main()
