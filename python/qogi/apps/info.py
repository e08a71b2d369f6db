"""`qogi info`: what a recording (or a FLIR file) holds, for people and scripts."""

from __future__ import annotations

import json
import math
import os

import numpy as np

from ..io.flir import FlirFile
from ..physics.radiometry import band_table

__all__ = ["recording_info", "flir_info", "format_recording_info", "format_flir_info"]


def _stats(a: np.ndarray) -> dict:
    finite = np.isfinite(a)
    n = int(finite.sum())
    if n == 0:
        return {"min": None, "mean": None, "max": None, "n_invalid": int(a.size)}
    v = a[finite].astype(np.float64)
    return {
        "min": float(v.min()),
        "mean": float(v.mean()),
        "max": float(v.max()),
        "n_invalid": int(a.size - n),
    }


def recording_info(rec) -> dict:
    """The recording's summary plus per-channel statistics of its first frame
    in both band radiance [W/(m2 sr)] and radiometric temperature [K]."""
    out = rec.summary()
    first = rec.frame(0)
    per_channel = []
    for k, ch in enumerate(rec.channels):
        table = band_table(ch)
        if rec.quantity == "radiance":
            lum = first[k]
            with np.errstate(invalid="ignore"):
                ok = np.isfinite(lum) & (lum > 0)
            temp = np.full(lum.shape, np.nan, np.float32)
            temp[ok] = table.temperature(lum[ok])
        else:
            temp = first[k]
            lum = table.radiance(temp)
        per_channel.append(
            {
                "index": k,
                "name": ch.name,
                "radiance_W_m2_sr": _stats(lum),
                "radiometric_temperature_K": _stats(temp),
            }
        )
    out["first_frame"] = per_channel
    return out


def _g(v, fmt="{:.6g}", none="-"):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return none
    return fmt.format(v)


def format_recording_info(info: dict) -> str:
    lines = []
    cam, fr, sc = info["camera"], info["frames"], info["scene"]
    lines.append(f"recording  {info['path']}  ({info['format']} v{info['version']})")
    netd = f", NETD {_g(cam['netd_K'])} K" if cam.get("netd_K") is not None else ""
    lines.append(
        f"camera     {cam['name'] or '(unnamed)'}: IFOV {cam['ifov_rad'] * 1e3:.4g} mrad, "
        f"{_g(cam['frame_rate_hz'])} Hz{netd}"
    )
    lines.append(f"channels   {len(info['channels'])}")
    for ch in info["channels"]:
        lo, hi = ch["band_cm1"]
        hlo, hhi = ch["half_max_cm1"]
        lines.append(
            f"  {ch['index']:>2}  {ch['name'] or '(unnamed)':<24} band {lo:.1f}-{hi:.1f} cm-1 "
            f"({ch['band_um'][0]:.3f}-{ch['band_um'][1]:.3f} um), half max "
            f"{hlo:.1f}-{hhi:.1f} cm-1, centroid {ch['centroid_cm1']:.1f} cm-1 "
            f"({ch['centroid_um']:.3f} um)"
        )
    lines.append(
        f"frames     T={fr['T']} C={fr['C']} H={fr['H']} W={fr['W']}, {fr['quantity']} "
        f"[{fr['unit']}]"
    )
    inval = "" if fr["n_invalid"] is None else f", {fr['n_invalid']} invalid values"
    lines.append(
        f"           {fr['duration_s']:.4g} s at {_g(cam['frame_rate_hz'])} Hz "
        f"(t = {fr['time_first_s']:.4g} .. {fr['time_last_s']:.4g} s){inval}"
    )
    parts = [
        f"distance {_g(sc['distance_m'])} m",
        f"ambient {_g(sc['ambient_temperature_K'])} K",
        f"pressure {_g(sc['pressure_Pa'])} Pa",
    ]
    for key, label, unit in (
        ("wind_speed_m_s", "wind", "m/s"),
        ("gas_temperature_K", "gas", "K"),
        ("background_temperature_K", "background", "K"),
    ):
        if sc.get(key) is not None:
            parts.append(f"{label} {_g(sc[key])} {unit}")
    if sc.get("species"):
        parts.append("species " + ", ".join(sc["species"]))
    lines.append("scene      " + ", ".join(parts))
    if "truth" in info:
        tr = info["truth"]
        rates = (
            ", ".join(
                f"{sp} {r:.6g} kg/s ({r * 3600:.6g} kg/h)"
                for sp, r in tr["emission_rate_kg_s"].items()
            )
            or "no rates"
        )
        ds = ", ".join(f"{k} {tuple(v)}" for k, v in tr["datasets"].items())
        lines.append("truth      " + rates + (f"; datasets: {ds}" if ds else ""))
    lines.append(
        "first frame, per channel: band radiance [W/(m2 sr)] and radiometric temperature [K]"
    )
    lines.append(
        f"  {'ch':>2}  {'name':<24} {'L min':>11} {'L mean':>11} {'L max':>11}"
        f" {'T min':>9} {'T mean':>9} {'T max':>9}"
    )
    for c in info["first_frame"]:
        L, T = c["radiance_W_m2_sr"], c["radiometric_temperature_K"]
        bad = f"  ({T['n_invalid']} invalid)" if T["n_invalid"] else ""
        lines.append(
            f"  {c['index']:>2}  {c['name'][:24]:<24} {_g(L['min'], '{:11.5g}'):>11} "
            f"{_g(L['mean'], '{:11.5g}'):>11} {_g(L['max'], '{:11.5g}'):>11} "
            f"{_g(T['min'], '{:9.3f}'):>9} {_g(T['mean'], '{:9.3f}'):>9} "
            f"{_g(T['max'], '{:9.3f}'):>9}{bad}"
        )
    return "\n".join(lines)


def flir_info(path) -> dict:
    """What a FLIR file holds: frames, size, camera, calibration, object
    parameters, time span, coding, and first-frame statistics of the raw
    counts, the apparent temperature and FLIR's object temperature."""

    with FlirFile(path) as f:
        n = len(f)
        first = f.frame(0)
        last_meta = f.metadata(n - 1)
        damaged = list(f.damaged)
    m = first.metadata
    out = {
        "path": os.fspath(path),
        "kind": f.kind,
        "n_frames": n,
        "damaged_frames": damaged,
        "metadata": m.as_dict(),
        "time_span_s": last_meta.timestamp_s - m.timestamp_s,
        "first_frame": {
            "raw_counts": _stats(first.raw.astype(np.float64)),
            "apparent_temperature_K": _stats(first.apparent_temperature()),
            "object_temperature_K": _stats(first.temperature()),
        },
    }
    return out


def format_flir_info(info: dict) -> str:
    m = info["metadata"]
    ff = info["first_frame"]
    coding = m["raw_format"] + (
        f" (NEAR={m['jpegls_near']} in frame 0: counts within +-{m['jpegls_near']})"
        if m["jpegls_near"]
        else ""
    )
    lines = [
        f"FLIR file  {info['path']}  ({info['kind']}, {info['n_frames']} frames, "
        f"{m['width']}x{m['height']}, {coding})",
        f"camera     {m['camera_model']} (s/n "
        f"{m['camera_serial_number']}), lens {m['lens_model']}, "
        f"FOV {m['field_of_view_deg']:.4g} deg, {m['frame_rate_hz']} Hz nominal",
        f"time       {m['datetime']}, span {info['time_span_s']:.4g} s",
        f"Planck     R1={m['planck_r1']:.8g} R2={m['planck_r2']:.8g} B={m['planck_b']:.8g} "
        f"F={m['planck_f']:.6g} O={m['planck_o']:.8g} (effective "
        f"{m['effective_wavenumber_cm1']:.1f} cm-1 = {1e4 / m['effective_wavenumber_cm1']:.3f} um)",
        f"object     emissivity {m['emissivity']:.3f}, distance {m['object_distance_m']:.3g} m, "
        f"reflected {m['reflected_temperature_K']:.2f} K, atmosphere "
        f"{m['atmospheric_temperature_K']:.2f} K, RH {m['relative_humidity'] * 100:.0f} %, "
        f"window {m['ir_window_temperature_K']:.2f} K / {m['ir_window_transmission']:.3f}",
        "first frame          min        mean       max",
    ]
    for key, label, fmt in (
        ("raw_counts", "raw counts", "{:10.1f}"),
        ("apparent_temperature_K", "apparent T [K]", "{:10.3f}"),
        ("object_temperature_K", "object T [K]", "{:10.3f}"),
    ):
        s = ff[key]
        lines.append(f"  {label:<16} {_g(s['min'], fmt)} {_g(s['mean'], fmt)} {_g(s['max'], fmt)}")
    lines += [f"warning: {msg}" for msg in info.get("damaged_frames", [])]
    lines.append(
        f"To make a recording: qogi convert {info['path']} -o OUT.h5 --camera "
        "<preset|response.csv> [--distance M] (or qogi.open_recording(path, camera=...))"
    )
    return "\n".join(lines)


def info_json(info: dict) -> str:
    return json.dumps(info, indent=2, default=lambda o: None if o is None else str(o))
