"""Blackbody radiance and camera channel responses.

Units: wavenumber ``nu_cm1`` in cm-1, temperature in K, spectral radiance in
W/(m2 sr cm-1), band radiance in W/(m2 sr).
"""

from __future__ import annotations

import csv
import os
import re
from typing import List, Optional, Tuple, Union

import numpy as np

from .. import _engine
from ..files import atomic_open

ArrayLike = Union[float, np.ndarray, list]

__all__ = ["SpectralResponse", "channel_problem", "planck_radiance", "planck_radiance_derivative"]


def _broadcast_call(fn, *args):
    arrays = np.broadcast_arrays(*[np.asarray(a, dtype=np.float64) for a in args])
    shape = arrays[0].shape
    out = fn(*[np.ascontiguousarray(a).ravel() for a in arrays])
    out = np.asarray(out).reshape(shape)
    return float(out) if out.ndim == 0 else out


def planck_radiance(nu_cm1: ArrayLike, temperature_K: ArrayLike):
    """Planck spectral radiance in wavenumber form.

    ``B(nu, T) = c1 nu^3 / (exp(c2 nu / T) - 1)`` in W/(m2 sr cm-1), with
    c1 = 2 h c^2 = 1.191042972e-8 W m2 sr-1 (per cm-1 units) and
    c2 = h c / k_B = 1.438776877 cm K.

    Parameters
    ----------
    nu_cm1 : float or array, cm-1
        Wavenumbers, >= 0.
    temperature_K : float or array, K
        Temperatures, > 0. Broadcast against ``nu_cm1``.

    Returns
    -------
    float or ndarray
        Spectral radiance, W/(m2 sr cm-1), shaped like the broadcast inputs.

    Raises
    ------
    ValueError
        For a negative or non-finite wavenumber or a non-positive temperature.
    """
    return _broadcast_call(_engine.planck_radiance, nu_cm1, temperature_K)


def planck_radiance_derivative(nu_cm1: ArrayLike, temperature_K: ArrayLike):
    """Temperature derivative dB/dT of :func:`planck_radiance`, W/(m2 sr cm-1 K)."""
    return _broadcast_call(_engine.planck_radiance_derivative, nu_cm1, temperature_K)


def _map(fn, values):
    a = np.asarray(values, dtype=np.float64)
    out = np.asarray(fn(np.ascontiguousarray(a).ravel())).reshape(a.shape)
    return float(out) if out.ndim == 0 else out


class SpectralResponse(_engine.SpectralResponse):
    """A camera channel's spectral response (filter x lens x detector).

    Piecewise linear between its samples, zero outside them.

    Parameters
    ----------
    nu_cm1 : array of float, cm-1
        Strictly increasing wavenumbers, finite and >= 0, at least 2 samples.
    response : array of float, dimensionless
        Same length as ``nu_cm1``; finite, >= 0, not all zero.
    name : str, default ""
        The channel's name.

    Examples
    --------
    >>> ch = SpectralResponse([2941.0, 3125.0], [1.0, 1.0], name="3.2-3.4 um")
    >>> round(ch.band_radiance(300.0), 4)  # W/(m2 sr)
    0.03
    """

    def __repr__(self) -> str:
        return (
            f"SpectralResponse(name={self.name!r}, {len(self.nu_cm1)} samples, "
            f"{self.nu_cm1[0]:.1f}-{self.nu_cm1[-1]:.1f} cm-1, "
            f"centroid {self.centroid_cm1:.1f} cm-1)"
        )

    @classmethod
    def from_wavelength_um(cls, wavelength_um, response, name: str = "") -> SpectralResponse:
        """Build from a response sampled in wavelength (um), any order.

        The response is taken as given per sample (no Jacobian is applied: a
        filter's transmittance is the same number in either axis).
        """
        wl = np.asarray(wavelength_um, dtype=float)
        r = np.asarray(response, dtype=float)
        if wl.shape != r.shape or wl.ndim != 1:
            raise ValueError(
                "wavelength_um and response must be 1-D arrays of the same "
                f"length; got shapes {wl.shape} and {r.shape}"
            )
        if np.any(~np.isfinite(wl)) or np.any(wl <= 0):
            raise ValueError("wavelength_um must be finite and > 0 um")
        nu = 1e4 / wl
        order = np.argsort(nu)
        return cls(nu[order], r[order], name)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, name: str | None = None) -> SpectralResponse:
        """Load a two-column CSV: wavenumber [cm-1] (or wavelength [um]), response.

        A header row is optional. If the header's first column mentions ``um``
        or ``wavelength``, the first column is read as wavelength in um.
        Comment lines start with ``#``.

        Raises
        ------
        ValueError
            Naming the file and line of a malformed row.
        """
        path = os.fspath(path)
        xs: List[float] = []
        ys: List[float] = []
        wavelength = False
        with open(path, newline="") as fh:
            for lineno, row in enumerate(csv.reader(fh), start=1):
                if not row or row[0].lstrip().startswith("#"):
                    continue
                if len(row) < 2:
                    raise ValueError(
                        f"{path}:{lineno}: expected two columns "
                        f"(wavenumber_cm1, response); got {row!r}"
                    )
                try:
                    x, y = float(row[0]), float(row[1])
                except ValueError:
                    if not xs:  # header
                        head = row[0].lower()
                        wavelength = "cm" not in head and (
                            "wavelength" in head
                            or "micro" in head
                            or re.search(r"\bum\b|\[um\]|_um", head) is not None
                        )
                        continue
                    raise ValueError(f"{path}:{lineno}: not a number in {row!r}") from None
                xs.append(x)
                ys.append(y)
        if name is None:
            name = os.path.splitext(os.path.basename(path))[0]
        if wavelength:
            return cls.from_wavelength_um(xs, ys, name)
        return cls(np.asarray(xs), np.asarray(ys), name)

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write ``wavenumber_cm1,response`` rows with a header."""

        with atomic_open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["wavenumber_cm1", "response"])
            for x, y in zip(self.nu_cm1, self.response):
                w.writerow([repr(float(x)), repr(float(y))])

    def evaluate(self, nu_cm1: ArrayLike):
        """Response at ``nu_cm1`` (linear interpolation, 0 outside the samples)."""
        return _map(self._evaluate, nu_cm1)

    def band_radiance(self, temperature_K: ArrayLike):
        """Band radiance of a blackbody, ``L = integral response B(nu, T) dnu``.

        Thesis eq. 14 for a blackbody scene. Returns W/(m2 sr), shaped like
        ``temperature_K``.
        """
        return _map(self._band_radiance, temperature_K)

    def band_radiance_derivative(self, temperature_K: ArrayLike):
        """dL/dT of :meth:`band_radiance`, W/(m2 sr K)."""
        return _map(self._band_radiance_derivative, temperature_K)

    def radiometric_temperature(self, band_radiance: ArrayLike):
        """Inverse of :meth:`band_radiance`: temperature [K] of the blackbody
        with this band radiance [W/(m2 sr)]. Accepts radiances of blackbodies
        between 10 K and 1e5 K; raises ValueError outside."""
        return _map(self._radiometric_temperature, band_radiance)


def channel_problem(
    channels, num_frame_channels: Optional[int] = None
) -> Optional[Tuple[str, str, str]]:
    """What is wrong with a camera's channel responses, or None: the one check
    of a channel list, whoever holds it.

    The channels must be at least one, each a :class:`SpectralResponse`, and
    (when ``num_frame_channels`` is given) exactly one per frame channel.
    Returns ``(location, problem, fix)``: ``location`` is ``""`` for the list
    or ``"/<k>"`` for channel k. The caller raises the type its input calls
    for: a :class:`qogi.RecordingError` (a DataError) for a recording's
    camera, a :class:`qogi.errors.UsageError` for a function's argument.
    """
    channels = list(channels)
    if not channels:
        return ("", "no channel response", "give one qogi.SpectralResponse per frame channel")
    for k, ch in enumerate(channels):
        if not isinstance(ch, _engine.SpectralResponse):
            return (
                f"/{k}",
                f"must be a qogi.SpectralResponse; got {type(ch).__name__}",
                "build it with qogi.SpectralResponse(nu_cm1, response, name) or "
                "SpectralResponse.from_csv(path)",
            )
    if num_frame_channels is not None and len(channels) != num_frame_channels:
        return (
            "",
            f"{len(channels)} channel responses for {num_frame_channels} frame channels",
            "give exactly one response per frame channel (axis 1 of the frames)",
        )
    return None
