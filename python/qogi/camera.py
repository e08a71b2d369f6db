"""``qogi.camera``: the camera model, calibration, noise and warm optics.

The path the documentation has always given (``from qogi.camera import ...``);
the code lives in :mod:`qogi.physics.camera`, at its place among the layers.
"""

from .physics.camera import *  # noqa: F403
from .physics.camera import __all__  # noqa: F401
