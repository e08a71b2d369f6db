"""Emission-rate units: one place that turns a mass rate into what a field
team reports (kg/h, g/h, kg/day, t/year, SLPM, scfh, mcf/day).

Mass units are exact scalings of kg/h. Volumetric units are the volume of the
**species itself** at the standard conditions :data:`STANDARD_CONDITIONS`
(ideal gas: ``V = m R T_std / (M p_std)``): 20 C (68 F) and 1 atm (101 325
Pa, 14.696 psia) — the conditions of many mass-flow controllers (SLPM) and of
the US EPA's greenhouse-gas reporting rule (40 CFR 98.6: 68 F, 14.7 psia).
The natural-gas industry's 60 F / 14.73 psia standard cubic foot is 1.9 %
smaller per mole; give ``standard=`` to use other conditions. ``mcf/day`` is
thousands of standard cubic feet of the species per day; a volume of
*natural gas* is that divided by the species' volume fraction in the gas.
A year is 365 days (8760 h, as emission inventories count).

>>> round(convert(1.0, "g/h"), 6)
1000.0
"""

from __future__ import annotations

from typing import Dict, Optional, Union

import numpy as np

from .errors import UsageError

__all__ = [
    "UNITS",
    "STANDARD_CONDITIONS",
    "R_GAS",
    "convert",
    "parse_unit",
    "is_volumetric",
    "kg_s_to_slpm",
    "standard_conditions_text",
    "unit_slug",
]

#: Standard conditions of the volumetric units: 20 C and 1 atm.
STANDARD_CONDITIONS = {"temperature_K": 293.15, "pressure_Pa": 101325.0}
#: Molar gas constant [J/(mol K)] (CODATA 2018, exact).
R_GAS = 8.314462618
#: One cubic foot [m3] (exact: 0.3048^3).
CUBIC_FOOT_M3 = 0.3048**3
HOURS_PER_YEAR = 8760.0

# Mass units: factor from kg/h. Volumetric units: factor from m3/h at standard conditions.
_MASS = {
    "kg/h": 1.0,
    "g/h": 1000.0,
    "kg/s": 1.0 / 3600.0,
    "kg/day": 24.0,
    "t/year": HOURS_PER_YEAR / 1000.0,
}
_VOLUME = {
    "SLPM": 1000.0 / 60.0,
    "scfh": 1.0 / CUBIC_FOOT_M3,
    "mcf/day": 24.0 / CUBIC_FOOT_M3 / 1000.0,
}
#: The units :func:`convert` accepts (canonical spellings).
UNITS = tuple(_MASS) + tuple(_VOLUME)
_ALIASES = {u.lower(): u for u in UNITS}
_ALIASES.update(
    {
        "kg/d": "kg/day",
        "t/y": "t/year",
        "t/yr": "t/year",
        "tpy": "t/year",
        "l/min": "SLPM",
        "slm": "SLPM",
        "scf/h": "scfh",
        "mscf/d": "mcf/day",
        "mcf/d": "mcf/day",
        "mcfd": "mcf/day",
    }
)


def parse_unit(text: str) -> str:
    """The canonical name of a rate unit (case-insensitive; a few common
    aliases such as ``tpy`` or ``mcfd`` accepted). Raises UsageError naming
    the accepted units."""
    u = _ALIASES.get(str(text).strip().lower())
    if u is None:
        raise UsageError(f"unknown rate unit {text!r}; use one of {', '.join(UNITS)}")
    return u


def is_volumetric(unit: str) -> bool:
    """True for units that are a gas volume at standard conditions."""
    return parse_unit(unit) in _VOLUME


def unit_slug(unit: str) -> str:
    """The unit as a column-name suffix: ``kg/h`` -> ``kg_h``, ``t/year`` -> ``t_year``."""
    return parse_unit(unit).replace("/", "_")


def convert(
    rate_kg_h,
    unit: str,
    molar_mass_kg_mol: Optional[float] = None,
    standard: Optional[Dict[str, float]] = None,
) -> Union[float, np.ndarray]:
    """A mass rate [kg/h] (scalar or array; NaN passes through) in ``unit``.

    Volumetric units need the species' molar mass [kg/mol]; ``standard``
    (``{"temperature_K", "pressure_Pa"}``) defaults to :data:`STANDARD_CONDITIONS`.
    """
    u = parse_unit(unit)
    x = np.asarray(rate_kg_h, dtype=float) if not isinstance(rate_kg_h, float) else rate_kg_h
    if u in _MASS:
        out = x * _MASS[u]
    else:
        if molar_mass_kg_mol is None or not molar_mass_kg_mol > 0:
            raise UsageError(
                f"{u} is a gas volume: it needs the species' molar mass; got {molar_mass_kg_mol!r}"
            )
        st = standard or STANDARD_CONDITIONS
        m3_per_kg = R_GAS * st["temperature_K"] / (molar_mass_kg_mol * st["pressure_Pa"])
        out = x * m3_per_kg * _VOLUME[u]
    if isinstance(out, np.ndarray) and out.ndim == 0:
        return float(out)
    return out


def kg_s_to_slpm(
    rate_kg_s: float, molar_mass_kg_mol: float, standard: Optional[Dict[str, float]] = None
) -> float:
    """Mass rate [kg/s] to standard litres per minute at ``standard`` conditions."""
    return float(convert(rate_kg_s * 3600.0, "SLPM", molar_mass_kg_mol, standard))


def standard_conditions_text(standard: Optional[Dict[str, float]] = None) -> str:
    """``"20 C (68 F), 101325 Pa (14.696 psia)"`` for the given conditions."""
    st = standard or STANDARD_CONDITIONS
    c = st["temperature_K"] - 273.15
    return (
        f"{c:.4g} C ({c * 9 / 5 + 32:.4g} F), {st['pressure_Pa']:.6g} Pa "
        f"({st['pressure_Pa'] / 6894.757293168:.5g} psia), ideal gas"
    )
