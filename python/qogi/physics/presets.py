"""Camera presets shipped with qogi (defined in the C++ engine, one source of truth)."""

from __future__ import annotations

from .. import _engine
from .camera import Camera
from .optics import SpectralResponse

__all__ = ["camera_preset", "camera_preset_names"]


def camera_preset_names() -> list[str]:
    """Names accepted by :func:`camera_preset`."""
    return list(_engine.camera_preset_names())


def camera_preset(name: str) -> Camera:
    """A shipped camera model.

    Parameters
    ----------
    name : str
        ``"gf320"`` (FLIR GF320: one cooled 3.2-3.4 um channel, 320x240, 15 Hz,
        NETD 15 mK, 24 deg lens) or ``"fast-m150"`` (four-position filter-wheel
        MWIR camera of the thesis: open, CO2, CH4 and CH4+H2O channels,
        320x256, 100 Hz, NETD 17 mK).

    Returns
    -------
    Camera
        With ``channels`` (a list of :class:`SpectralResponse`, filter x lens x
        detector), ``ifov_rad``, ``frame_rate_hz``, ``netd_K``, ``width``,
        ``height`` and a ``description`` saying where every number comes from
        and what is approximated (the real filter curves are not public).

    Raises
    ------
    ValueError
        For an unknown name (the message lists the known ones).
    """
    m = _engine.camera_preset(name)
    channels = [SpectralResponse(ch.nu_cm1, ch.response, ch.name) for ch in m.channels]
    return Camera(
        name=m.name,
        ifov_rad=m.ifov_rad,
        channels=channels,
        frame_rate_hz=m.frame_rate_hz,
        netd_K=m.netd_K,
        width=m.width,
        height=m.height,
        description=m.description,
    )
