"""How much the filter wheel's channel time offsets move a rate (docs/recording.md,
"How the pipeline treats the channel time offset").

A synthetic heated-methane release seen by the four-filter fast-m150 is rendered
at 4 x 100 Hz; two four-channel recordings are built from it at 100 turns/s:
"simultaneous" takes every channel of turn i from frame 4 i + 2 (one instant), and
"wheel" takes channel k from frame 4 i + k (each filter at its own time, 2.5 ms
apart, as the wheel sees the plume), written as a Telops .hcc and read back by
qogi.open_recording. They are quantified the same way (temperature inferred, the
release's exit velocity) and the rates compared: "wheel" with the pipeline's
filter-wheel timing correction (qogi.pipeline.align: each channel moved along
the gas's measured flow to the turn's time), "wheel, uncorrected" the same
recording without its channel offsets (what the pipeline did before).

    python scripts/channel_offset_effect.py [--duration 0.2] [--seed 5]
"""

from __future__ import annotations

import argparse
import os
import tempfile

import numpy as np

import qogi
from qogi.io.telops import write_hcc
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import truth_surfaces
from qogi.synth import render


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=0.2)
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args()
    out, infos, offsets, n = wheel_rates(
        args.duration, args.seed, tempfile.mkdtemp(prefix="qogi-offset-")
    )
    print("turns:", n, "channel offsets [ms]:", np.round(offsets * 1e3, 3))
    for name, v in out.items():
        print(f"{name:>18}: " + "  ".join(f"{x:.5g}" for x in v) + " kg/h (4, 8, 12 cm)")
    for name, v in infos.items():
        print(f"{name:>18}: {v}")
    for name in ("wheel, uncorrected", "wheel"):
        print(
            f"{name} / simultaneous - 1: "
            + "  ".join(f"{x:+.2%}" for x in out[name] / out["simultaneous"] - 1)
        )


def wheel_rates(duration_s: float, seed: int, d: str):
    """The three rates (kg/h at 4, 8 and 12 cm) of the heated release seen
    through the fast-m150 for ``duration_s`` (rendered at 400 frames/s into
    the folder ``d``, seed ``seed``): ``{"simultaneous", "wheel, uncorrected",
    "wheel"}``; their infos (temperature and mixing line, pixel status); the
    wheel's channel offsets [s]; the number of turns."""
    fast = os.path.join(d, "fast.h5")
    render.synthesize(
        "lab-heated-ch4-55c-gf320",
        fast,
        duration_s=duration_s,
        seed=seed,
        camera_name="fast-m150",
        frame_rate_hz=400.0,
        truth_maps=True,
    )
    with qogi.open_recording(fast) as rec:
        L = rec.to_array()
        n = rec.n_frames // 4
        t = rec.time_s
        surfs, source = truth_surfaces(rec, heights_m=[0.04, 0.08, 0.12], half_width_px=50)
        cam = qogi.Camera(
            rec.camera.name, rec.camera.ifov_rad, rec.channels, None, rec.camera.netd_K
        )
        sim = qogi.Recording.from_arrays(
            L[2 : 4 * n : 4], t[2 : 4 * n : 4], quantity="radiance", camera=cam, scene=rec.scene
        )
        frames, times, pos = [], [], []
        for i in range(n):
            for k in range(4):
                frames.append(L[4 * i + k, k])
                times.append(1.7e9 + t[4 * i + k])
                pos.append(k)
        hcc = os.path.join(d, "wheel.hcc")
        write_hcc(hcc, frames, times, fw_positions=pos, calibration_mode=3, frame_rate_hz=400.0)
        scene = rec.scene
    wheel = qogi.open_recording(
        hcc,
        camera="fast-m150",
        distance_m=scene.distance_m,
        ambient_temperature_K=scene.ambient_temperature_K,
    )
    cfg = QuantifyConfig(
        species=["CH4"],
        gas_temperature="infer",
        velocity="exit",
        exit_velocity_m_s=1.0,
        source=source,
    )
    blind = qogi.Recording(
        source=wheel.to_array(),
        time_s=wheel.time_s,
        quantity=wheel.quantity,
        camera=wheel.camera,
        scene=wheel.scene,
        truth=None,
        path=wheel.path,
        nonfinite=wheel.nonfinite,
        attrs={k: v for k, v in wheel.attrs.items() if k != "channel_time_offset_s"},
    )
    out, infos = {}, {}
    for name, r in (("simultaneous", sim), ("wheel, uncorrected", blind), ("wheel", wheel)):
        res = quantify(r, surfs, cfg)
        out[name] = np.array([s.species["CH4"].mean_kg_h for s in res.surfaces])
        infos[name] = {k: v for k, v in res.info.items() if "temperature" in k or "mixing" in k}
        infos[name]["pixels"] = res.pixel_status
    return out, infos, np.asarray(wheel.attrs["channel_time_offset_s"], float), n


if __name__ == "__main__":
    main()
