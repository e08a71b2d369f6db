"""The default flow on motion with rotation and shear (issue 20): rigid motion
of a real infrared frame and of a synthetic column texture, and a rotating
vortex pair in a column field.

Where the flow is divergence-free, mass conservation and brightness constancy
coincide, so the exact next frame is the first one evaluated at the
back-traced positions. Truth: the known map, not the code's output. Bound:
mean end-point error <= 0.2 px over the interior (16 px margin) for the
default method, from a cold start and in a warm-started sequence (<= 0.1 px
on the real frame, where the method before the patch-search start read
0.13-0.19 px).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import qogi
from qogi import io as qio
from qogi.measure import velocimetry as vel

H, W = 256, 320
MARGIN = 16


def rigid(frame, theta, dx, dy):
    """The frame moved by phi(x) = c + R(theta) (x - c) + d (c the centre),
    rendered by bicubic interpolation at phi^-1(x), and the exact forward
    displacement phi(x) - x [px/frame]."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    cx, cy = W / 2, H / 2
    c, s = np.cos(theta), np.sin(theta)
    bx = cx + c * (x - cx - dx) + s * (y - cy - dy)
    by = cy - s * (x - cx - dx) + c * (y - cy - dy)
    nxt = cv2.remap(
        frame.astype(np.float32),
        bx.astype(np.float32),
        by.astype(np.float32),
        cv2.INTER_CUBIC,
        borderMode=cv2.BORDER_REFLECT,
    )
    tu = cx + c * (x - cx) - s * (y - cy) + dx - x
    tv = cy + s * (x - cx) + c * (y - cy) + dy - y
    return nxt, tu, tv


def mean_epe(u, v, tu, tv, valid):
    sl = (slice(MARGIN, -MARGIN), slice(MARGIN, -MARGIN))
    ok = valid[sl]
    assert ok.mean() > 0.95
    return float(np.hypot(u - tu, v - tv)[sl][ok].mean())


# Rotation + translation, 1-3 px/frame over the interior.
MOTIONS = [(0.008, 1.5, -1.0), (-0.006, -0.6, 0.9), (0.012, 0.0, 0.0)]


@pytest.fixture(scope="module")
def ir_column(shared_dir):
    """A real infrared scene (FLIR sample, 640 x 480, a hummingbird at a
    feeder: weak texture, large smooth areas) as a column-like field: the
    temperature excess over the scene's 1st percentile, clipped at zero,
    centre 320 x 256 crop."""
    path = shared_dir / "samples" / "flir" / "SampleSEQ.seq"
    if not path.is_file():
        pytest.skip(f"FLIR sample not found at {path}")
    temp = np.asarray(qio.read_flir(path)[0].temperature(), np.float64)
    y0, x0 = (temp.shape[0] - H) // 2, (temp.shape[1] - W) // 2
    crop = temp[y0 : y0 + H, x0 : x0 + W]
    return np.clip(crop - np.percentile(crop, 1), 0, None).astype(np.float32)


def synthetic_column(seed=11, n=48):
    """A positive band-limited random texture (wavelengths 6-24 px) on a
    Gaussian envelope: a column-like field with texture everywhere."""
    rng = np.random.default_rng(seed)
    lam = rng.uniform(6.0, 24.0, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    ph = rng.uniform(0, 2 * np.pi, n)
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    t = np.zeros((H, W))
    for i in range(n):
        k = 2 * np.pi / lam[i]
        t += np.cos(k * np.cos(ang[i]) * x + k * np.sin(ang[i]) * y + ph[i])
    env = 0.3 + np.exp(-((x - W / 2) ** 2 / (2 * 120.0**2) + (y - H / 2) ** 2 / (2 * 100.0**2)))
    return (env * np.exp(0.3 * t * np.sqrt(2.0 / n))).astype(np.float32)


@pytest.mark.parametrize("theta, dx, dy", MOTIONS)
def test_default_flow_follows_rigid_motion_of_a_real_infrared_frame(ir_column, theta, dx, dy):
    nxt, tu, tv = rigid(ir_column, theta, dx, dy)
    speed = np.hypot(tu, tv)[MARGIN:-MARGIN, MARGIN:-MARGIN]
    assert 0.5 < speed.mean() < 3.0 and speed.max() < 3.5
    f = qogi.optical_flow(ir_column, nxt)
    assert f.method == vel.DEFAULT_METHOD
    # Target 0.2 px (issue 20); the default reads ~0.05 px here, the fluid
    # method before the patch-search start 0.13-0.19 px.
    assert mean_epe(f.u, f.v, tu, tv, f.valid) <= 0.1


@pytest.mark.parametrize("theta, dx, dy", MOTIONS)
def test_default_flow_follows_rigid_motion_of_a_synthetic_column(theta, dx, dy):
    col = synthetic_column()
    nxt, tu, tv = rigid(col, theta, dx, dy)
    f = qogi.optical_flow(col, nxt)
    assert mean_epe(f.u, f.v, tu, tv, f.valid) <= 0.2


def vortex_velocity(x, y, peak=2.5, core=24.0, separation=70.0, drift=(0.6, -0.4)):
    """Two counter-rotating Lamb-Oseen vortices (peak swirl `peak` px/frame at
    1.12 core radii) side by side at the centre, plus a uniform drift:
    divergence-free, with strong shear between the cores."""
    u = np.full(np.shape(x), drift[0])
    v = np.full(np.shape(x), drift[1])
    gamma = peak * 2 * np.pi * core / 0.6382  # v_theta max = 0.6382 gamma / (2 pi core)
    for cx, sign in ((W / 2 - separation / 2, 1.0), (W / 2 + separation / 2, -1.0)):
        dx, dy = x - cx, y - H / 2
        r2 = dx * dx + dy * dy + 1e-12
        f = sign * gamma / (2 * np.pi * r2) * (1 - np.exp(-r2 / core**2))
        u = u - f * dy
        v = v + f * dx
    return u, v


def trace(x, y, dt, steps=16):
    """Positions after time dt [frames] along the vortex flow (RK4)."""
    h = dt / steps
    for _ in range(steps):
        k1 = vortex_velocity(x, y)
        k2 = vortex_velocity(x + h / 2 * k1[0], y + h / 2 * k1[1])
        k3 = vortex_velocity(x + h / 2 * k2[0], y + h / 2 * k2[1])
        k4 = vortex_velocity(x + h * k3[0], y + h * k3[1])
        x = x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        y = y + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return x, y


@pytest.fixture(scope="module")
def vortex_pair():
    """Four frames of a column field advected by the steady vortex pair, each
    rendered exactly (the texture evaluated at the back-traced positions), 0.5 %
    noise; the exact forward displacement of every pair."""
    rng = np.random.default_rng(5)
    n = 48
    lam = rng.uniform(6.0, 24.0, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    ph = rng.uniform(0, 2 * np.pi, n)
    kx, ky = 2 * np.pi / lam * np.cos(ang), 2 * np.pi / lam * np.sin(ang)

    def column(px, py):
        t = np.zeros(px.shape)
        for i in range(n):
            t += np.cos(kx[i] * px + ky[i] * py + ph[i])
        env = 0.2 + np.exp(
            -((px - W / 2) ** 2 / (2 * 110.0**2) + (py - H / 2) ** 2 / (2 * 90.0**2))
        )
        return env * np.exp(0.4 * t * np.sqrt(2.0 / n))

    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    frames, px, py = [], x.copy(), y.copy()
    for _ in range(4):
        frames.append(column(px, py))
        px, py = trace(px, py, -1.0)
    fx, fy = trace(x, y, 1.0)
    frames = np.array(frames, np.float32)
    frames += rng.normal(0, 0.005 * frames.std(), frames.shape).astype(np.float32)
    return frames, fx - x, fy - y


def test_default_flow_resolves_a_rotating_vortex_pair(vortex_pair):
    frames, tu, tv = vortex_pair
    speed = np.hypot(tu, tv)
    assert speed.max() > 2.5  # the cores' swirl, with the drift
    f = qogi.optical_flow(frames[0], frames[1])
    assert mean_epe(f.u, f.v, tu, tv, f.valid) <= 0.2
    # The sequence (each pair warm-started from the previous one) too.
    seq = qogi.optical_flow_sequence(frames)
    for k in range(len(seq)):
        assert mean_epe(seq.u[k], seq.v[k], tu, tv, seq.valid[k]) <= 0.2
    # The vorticity at the cores has the right sign and size: the curl of
    # the displacement [1/frame] averaged within 12 px of each core.
    yy, xx = np.mgrid[0:H, 0:W]
    curl = np.gradient(f.v, axis=1) - np.gradient(f.u, axis=0)
    true_curl = np.gradient(tv, axis=1) - np.gradient(tu, axis=0)
    for cx in (W / 2 - 35, W / 2 + 35):
        core = (xx - cx) ** 2 + (yy - H / 2) ** 2 <= 12**2
        assert curl[core].mean() == pytest.approx(true_curl[core].mean(), rel=0.2)
