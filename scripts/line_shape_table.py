"""The line-shape table of docs/forward_model.md ("Line shape").

For thin and thick, cold and hot methane plumes in front of the GF320 lab
plate (and CH4/CO2 through fast-m150's CO2 and CH4 channels), the band
contrast under each line-shape rule relative to qogi's default
(fixed:25+self), and the column qogi's default retrieves from a contrast
made with each rule (single channel, the temperature known), relative to
the true column.

Usage:
    .venv/bin/python scripts/line_shape_table.py
"""

from __future__ import annotations

import sys

import numpy as np

import qogi
from qogi.physics.forward import forward_model

RULES = ("fixed:25+self", "hapi+self", "fixed:25+air", "hapi+air")
#: (label, CH4 peak fraction, sigma [m], peak temperature [K]); ambient 295 K, plate 285 K.
PLUMES = [
    ("thin, cold: 1 cm deep, 3 % CH4", 0.03, 0.01 / 2.3548, 295.0),
    ("thin, hot: 1 cm, 3 %, 330 K", 0.03, 0.01 / 2.3548, 330.0),
    ("thick, cold: 5 cm deep, 50 % CH4", 0.5, 0.05 / 2.3548, 295.0),
    ("thick, hot: 5 cm, 50 %, 330 K", 0.5, 0.05 / 2.3548, 330.0),
    ("core, cold: 2 cm, 100 % CH4", 1.0, 0.02 / 2.3548, 295.0),
]
T_AMB, T_BG = 295.0, 285.0


def retrieved_column(model, channel, contrast, t_peak, sigma):
    """The column the model retrieves from a contrast at known temperature
    and depth (monotone lookup over the peak fraction)."""
    x = np.geomspace(1e-6, 1.0, 400)
    c = (
        model.band_radiance({"CH4": x}, t_peak, sigma, T_AMB, T_BG)[:, channel]
        - model.background_radiance(T_BG)[channel]
    )
    col = model.column_density({"CH4": x}, t_peak, sigma, T_AMB)["CH4"]
    keep = np.concatenate([[True], np.diff(c) > 0])
    return float(np.interp(contrast, c[keep], col[keep]))


def main() -> int:
    cam = qogi.camera_preset("gf320")
    models = {r: forward_model(cam.channels, ["CH4"], line_shape=r) for r in RULES}
    default = models[RULES[0]]
    print(
        "GF320 (3.2-3.4 um), plate 285 K, ambient 295 K. Per rule: band contrast / default's "
        "contrast; column the default retrieves from that rule's contrast / true column.\n"
    )
    print("| plume | " + " | ".join(RULES) + " |")
    print("|---|" + "---|" * len(RULES))
    for label, x, sigma, tp in PLUMES:
        truth = default.column_density({"CH4": x}, tp, sigma, T_AMB)["CH4"]
        base = float(
            default.band_radiance({"CH4": x}, tp, sigma, T_AMB, T_BG)[0]
            - default.background_radiance(T_BG)[0]
        )
        cells = []
        for r in RULES:
            m = models[r]
            c = float(
                m.band_radiance({"CH4": x}, tp, sigma, T_AMB, T_BG)[0]
                - m.background_radiance(T_BG)[0]
            )
            col = retrieved_column(default, 0, c, tp, sigma)
            cells.append(f"{c / base:.3f} / {col / truth:.3f}")
        print(f"| {label} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
