"""How much do a warm filter and lens add to what the fast-m150 measures?

Prints, for each fast-m150 channel with the optics at 20 C in front of a
15 C background: the background's band radiance through the channel, the
warm-optics radiance W (lens and filter terms), the apparent (radiometric)
background temperature the detector would report if W were ignored, and the
drift per kelvin of optics temperature in apparent scene kelvin. Two filter
models: absorbing (reflectance 0, the default) and an interference filter
that rejects by reflection, with emissivity 0.05 at every wavenumber.

Run: .venv/bin/python examples/warm_optics_effect.py
"""

from __future__ import annotations

import numpy as np

from qogi.physics.camera import ChannelOptics, camera_optics

T_OPTICS = 293.15  # 20 C
T_BG = 288.15  # 15 C
EMISSIVITY = 0.05  # interference filter: out-of-band rejection by reflection


def reflective(o: ChannelOptics) -> ChannelOptics:
    tau = o.filter_transmittance
    rho = np.clip(1.0 - tau - EMISSIVITY, 0.0, None)
    return ChannelOptics(o.nu_cm1, o.detector_response, tau, o.lens_transmittance, rho, o.name)


def main() -> None:
    print(
        f"fast-m150, optics at {T_OPTICS - 273.15:.0f} C, background {T_BG - 273.15:.0f} C "
        "(radiances in W/(m2 sr))"
    )
    print(
        f"{'channel':22s} {'filter':10s} {'L_bg':>8s} {'W_lens':>8s} {'W_filter':>9s} "
        f"{'W/L_bg':>7s} {'T_app [K]':>10s} {'dT_app/dT_opt':>14s}"
    )
    for o in camera_optics("fast-m150"):
        for label, opt in (("absorbing", o), (f"eps={EMISSIVITY}", reflective(o))):
            if label != "absorbing" and np.all(o.filter_transmittance == 1.0):
                continue  # open position: no filter
            r = opt.response
            l_bg = r.band_radiance(T_BG)
            w_l, w_f = opt.lens_term(T_OPTICS), opt.filter_term(T_OPTICS)
            w = w_l + w_f
            t_app = r.radiometric_temperature(l_bg + w)
            drift = (
                opt.warm_radiance_derivative_lens(T_OPTICS)
                + opt.warm_radiance_derivative_filter(T_OPTICS)
            ) / r.band_radiance_derivative(t_app)
            print(
                f"{o.name:22s} {label:10s} {l_bg:8.4f} {w_l:8.4f} {w_f:9.4f} "
                f"{w / l_bg:7.3f} {t_app:10.2f} {drift:14.2f}"
            )


if __name__ == "__main__":
    main()
