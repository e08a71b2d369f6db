"""Writes tests/data/flux_reference.npz: outputs of the numpy transport flux,
flux level and surface flux on the seeded inputs of tests/python/flux_cases.py.

Run once on the numpy implementation (commit 6f8e8db, before the flux module
moved into the engine): the comparison test checks the engine against these.
Re-running it now would compare the engine with itself."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

import flux_cases as fc  # noqa: E402

from qogi.measure import velocimetry as vel  # noqa: E402
from qogi.pipeline.flux import _surface_flux  # noqa: E402


def main() -> None:
    out = {}
    for name, seed, axis, src, kind in fc.TRANSPORT_CASES:
        frames = fc.turned(fc.puffing_plume(seed), axis)
        r = fc.intervals(kind, frames.shape[0], seed)
        tf = vel.transport_flux(frames, axis, src, intervals=r)
        for f in ("flux", "line_column", "velocity", "displacement"):
            out[f"tf_{name}_{f}"] = getattr(tf, f)
        out[f"td_{name}"] = vel.typical_displacement(frames, axis)
        for level_name, level in (("slow", 1.6), ("backwards", -3.0)):
            fu, fv = fc.frame_velocities(seed, frames.shape, axis, level)
            u, v, scale = vel.calibrate_flux_level(
                None, frames, axis, src, frame_velocities=(fu, fv)
            )
            out[f"cal_{name}_{level_name}_u"] = fc.digest(u)
            out[f"cal_{name}_{level_name}_v"] = fc.digest(v)
            out[f"cal_{name}_{level_name}_scale"] = scale
    # A flow sequence and a given transport of a sub-stretch, smoothing off.
    frames, fu, fv, seq = fc.flow_sequence_case()
    u, v, scale = vel.calibrate_flux_level(seq, frames, "up", None, smooth_px=0.0)
    out["cal_seq_u"], out["cal_seq_v"], out["cal_seq_scale"] = fc.digest(u), fc.digest(v), scale
    u, v, scale = fc.calibrate_given_transport(frames, fu, fv)
    out["cal_part_u"], out["cal_part_v"], out["cal_part_scale"] = fc.digest(u), fc.digest(v), scale
    for seed in (1, 2):
        c, sig, vn, dl = fc.surface_case(seed)
        sf = _surface_flux(c, sig, vn, dl)
        out[f"sf_{seed}_rate"] = sf.rate
        out[f"sf_{seed}_pixels"] = sf.pixels
        out[f"sf_{seed}_column_variance"] = sf.column_variance
    np.savez_compressed(ROOT / "tests" / "data" / "flux_reference.npz", **out)
    print(
        f"{len(out)} arrays; "
        + ", ".join(f"{k}={float(np.nansum(v)):.6g}" for k, v in out.items() if k.startswith("td_"))
    )


if __name__ == "__main__":
    main()
