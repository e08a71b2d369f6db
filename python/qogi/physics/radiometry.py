"""Fast conversion between radiometric temperature and band radiance.

A camera channel with spectral response ``r(nu)`` sees a blackbody at
temperature ``T`` as the band radiance (thesis eq. 14 for a blackbody scene)

    L(T) = integral r(nu) B(nu, T) dnu        [W/(m2 sr)]

and a measured band radiance ``L`` as the radiometric temperature
``T = L^-1(L)``: the temperature of the blackbody that would give it.
:meth:`qogi.SpectralResponse.band_radiance` and
:meth:`~qogi.SpectralResponse.radiometric_temperature` evaluate these exactly
(quadrature and a safeguarded Newton solve) but cost microseconds to
milliseconds per value; a video has ~10^8 values.

:class:`BandTable` tabulates each direction once per channel (the engine's
``RadiometricTable``, ``cpp/engine/camera/radiometric_table.h``: the one L(T)
table of qogi) and interpolates it with cubic Hermite polynomials whose node
slopes are exact derivatives:

- ``T -> L``: ``ln L`` as a function of ``u = 1/T`` on a uniform grid in
  ``u``. In the Wien limit ``ln L`` is linear in ``u`` (slope
  ``-c2 nu_eff``), so the cubic only has to absorb the band's spread.
- ``L -> T``: ``u = 1/T`` as a function of ``ln L`` on a uniform grid in
  ``ln L`` (node temperatures from Newton iterations on the exact
  ``L(T)``).

Uniform grids make the lookup a multiply and a floor, so a 320x256x4 frame
converts in milliseconds. Values outside the table's temperature range fall
back to the exact engine calls (slow, never clamped). Measured interpolation
error against the exact engine calls (``benchmarks/bench_radiometry.py`` and
``tests/python/test_radiometry.py``), for bands from a 3.2-3.4 um filter to
the whole 1.5-5.4 um InSb band and 7.5-13 um LWIR: relative radiance error
below 1e-9 and temperature error below 1e-7 K over 150-1500 K, i.e. far below
float32 resolution (6e-8 relative, 2e-5 K at 300 K).
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from typing import List, Sequence, Union

import numpy as np

from .. import _engine
from .optics import SpectralResponse

__all__ = ["BandTable", "band_table", "temperature_to_radiance", "radiance_to_temperature"]


def _tabulated(x, lo: float, hi: float, table, exact) -> np.ndarray:
    """``table`` where lo <= x <= hi, ``exact`` elsewhere, NaN for NaN; any
    shape, float32 in gives float32 out (else float64)."""
    a = np.asarray(x)
    out_dtype = np.float32 if a.dtype == np.float32 else np.float64
    xx = a.astype(np.float64, copy=False)
    inside = (xx >= lo) & (xx <= hi)
    out = table(np.where(inside, xx, lo))
    outside = ~inside & np.isfinite(xx)
    if np.any(outside):
        out[outside] = exact(xx[outside])
    out[~np.isfinite(xx)] = np.nan
    return out.astype(out_dtype, copy=False)


class BandTable:
    """Per-channel lookup between radiometric temperature [K] and band radiance [W/(m2 sr)].

    Parameters
    ----------
    channel : SpectralResponse
        The channel's spectral response.
    t_min_K, t_max_K : float, K, default 150 and 1500
        Temperature range covered by the tables. Values outside it are
        converted with the exact (slow) engine calls.
    nodes : int, default 1024
        Table size in each direction.
    """

    def __init__(
        self,
        channel: SpectralResponse,
        t_min_K: float = 150.0,
        t_max_K: float = 1500.0,
        nodes: int = 1024,
    ):
        if not isinstance(channel, SpectralResponse):
            raise TypeError(
                f"channel must be a qogi.SpectralResponse; got {type(channel).__name__}"
            )
        if not (np.isfinite(t_min_K) and np.isfinite(t_max_K) and 10.0 < t_min_K < t_max_K < 1e5):
            raise ValueError(
                "t_min_K and t_max_K must satisfy 10 < t_min_K < t_max_K < 1e5 K; "
                f"got {t_min_K} and {t_max_K}"
            )
        if int(nodes) < 16:
            raise ValueError(f"nodes must be >= 16; got {nodes}")
        n = int(nodes)
        self.channel = channel
        self.t_min_K = float(t_min_K)
        self.t_max_K = float(t_max_K)
        self.nodes = n
        # The engine's table (engine/camera/radiometric_table.h: ln L cubic
        # Hermite in 1/T, 1/T cubic Hermite in ln L, exact node slopes): the
        # one L(T) implementation.
        self._table = _engine.RadiometricTable(channel, self.t_min_K, self.t_max_K, n)
        self.radiance_min = float(self._table.radiance_min)
        self.radiance_max = float(self._table.radiance_max)

    def __repr__(self) -> str:
        return (
            f"BandTable({self.channel.name!r}, {self.t_min_K:g}-{self.t_max_K:g} K, "
            f"{self.nodes} nodes)"
        )

    def radiance(self, temperature_K) -> np.ndarray:
        """Band radiance [W/(m2 sr)] of blackbodies at ``temperature_K`` [K].

        Any shape; float32 input gives float32 output, otherwise float64.
        NaN stays NaN.
        """
        return _tabulated(
            temperature_K,
            self.t_min_K,
            self.t_max_K,
            self._table.radiance,
            self.channel.band_radiance,
        )

    def temperature(self, radiance) -> np.ndarray:
        """Radiometric temperature [K] of band radiances [W/(m2 sr)].

        Any shape; float32 input gives float32 output. NaN stays NaN. A
        radiance outside the table goes to the exact engine inverse, which
        raises ValueError for values no blackbody of 10-1e5 K gives
        (e.g. <= 0).
        """
        return _tabulated(
            radiance,
            self.radiance_min,
            self.radiance_max,
            self._table.temperature,
            self.channel.radiometric_temperature,
        )


_CACHE: OrderedDict[bytes, BandTable] = OrderedDict()
_CACHE_SIZE = 32


def band_table(channel: SpectralResponse) -> BandTable:
    """The default :class:`BandTable` of ``channel``, cached by the channel's
    response samples (building one takes ~0.1-1 s)."""
    h = hashlib.sha1(np.asarray(channel.nu_cm1).tobytes())
    h.update(np.asarray(channel.response).tobytes())
    key = h.digest()
    table = _CACHE.get(key)
    if table is None:
        table = BandTable(channel)
        _CACHE[key] = table
        if len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)
    else:
        _CACHE.move_to_end(key)
    return table


def _per_channel(values, channels: Sequence[SpectralResponse], axis: int, fn_name: str):
    a = np.asarray(values)
    if a.ndim == 0:
        raise ValueError("frames must have a channel axis; got a scalar")
    ax = axis % a.ndim
    if a.shape[ax] != len(channels):
        raise ValueError(
            f"frames have {a.shape[ax]} channels on axis {axis} but "
            f"{len(channels)} channel responses were given"
        )
    out = np.empty(a.shape, dtype=np.float32 if a.dtype == np.float32 else np.float64)
    for k, ch in enumerate(channels):
        idx: List[Union[slice, int]] = [slice(None)] * a.ndim
        idx[ax] = k
        out[tuple(idx)] = getattr(band_table(ch), fn_name)(a[tuple(idx)])
    return out


def temperature_to_radiance(frames, channels: Sequence[SpectralResponse], axis: int = -3):
    """Radiometric temperature frames [K] -> band radiance [W/(m2 sr)].

    ``frames`` has the channel on ``axis`` (default -3: (..., C, H, W)),
    one :class:`SpectralResponse` per channel. Uses the cached
    :class:`BandTable` of each channel.
    """
    return _per_channel(frames, channels, axis, "radiance")


def radiance_to_temperature(frames, channels: Sequence[SpectralResponse], axis: int = -3):
    """Band radiance frames [W/(m2 sr)] -> radiometric temperature [K];
    the inverse of :func:`temperature_to_radiance`."""
    return _per_channel(frames, channels, axis, "temperature")
