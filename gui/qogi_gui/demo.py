"""The demo scene: a synthetic release with exact ground truth, one click away.

The demo is a short run of one of the thesis presets of :mod:`qogi.synth.plume`
(simulated plume, rendered through the preset camera), written once to the
user's cache folder and reused afterwards. Its ``/truth`` lets the viewer show
the estimated emission rate next to the true one.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Optional, Tuple

from .jobs import Stopped

__all__ = ["DEMO", "demo_path", "source_pixel", "ensure_demo"]

#: What the demo scene is: a preset of qogi.synth.plume, how long, at what rate, which seed.
DEMO = {"preset": "lab-ch4-5slpm-gf320", "duration_s": 4.0, "frame_rate_hz": None, "seed": 1}


def demo_path(folder: Optional[os.PathLike] = None) -> Path:
    """Where the demo recording is kept (one file per demo definition, qogi
    version and recording format version, :func:`qogi.cache.cache_path`)."""
    from qogi import __version__
    from qogi.cache import cache_path
    from qogi.contract import VERSION

    rate = DEMO["frame_rate_hz"]
    stem = (
        f"{DEMO['preset']}_{DEMO['duration_s']:g}s"
        f"{'' if rate is None else f'_{rate:g}Hz'}_seed{DEMO['seed']}_qogi{__version__}"
    )
    path = cache_path("demo", stem, VERSION, ".h5")
    return path if folder is None else Path(folder) / path.name


def source_pixel() -> Tuple[float, float]:
    """Pixel (x, y) of the demo release's exit (from the preset)."""
    from qogi import synth

    x, y = synth.preset(DEMO["preset"])["scene"]["exit_pixel"]
    return float(x), float(y)


def _valid(path: Path) -> bool:
    from qogi import open_recording

    try:
        with open_recording(path, check_frames=False):
            return True
    except (ValueError, OSError):
        return False


def ensure_demo(
    progress: Callable[[float, str], bool], folder: Optional[os.PathLike] = None
) -> str:
    """The demo recording's path, synthesising it first if it is not cached.

    ``progress(fraction, message)`` is told how far the synthesis is; when it
    returns False the work stops (:class:`qogi_gui.jobs.Stopped`) and nothing
    is left behind.
    """
    path = demo_path(folder)
    if path.exists() and _valid(path):
        return str(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + f".part{os.getpid()}.h5")
    try:
        _synthesise(tmp, progress)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return str(path)


def _synthesise(path: Path, progress: Callable[[float, str], bool]) -> None:
    """Simulate and render the demo (what ``qogi synth`` does) into ``path``."""
    from qogi.errors import Cancelled
    from qogi.synth.render import synthesize

    try:
        synthesize(
            DEMO["preset"],
            str(path),
            duration_s=DEMO["duration_s"],
            frame_rate_hz=DEMO["frame_rate_hz"],
            seed=DEMO["seed"],
            progress=lambda f, m: progress(f, f"demo scene: {m}"),
        )
    except (Cancelled, KeyboardInterrupt):  # a cancelled progress callback, or Ctrl-C
        raise Stopped("the demo scene was cancelled") from None
