"""``qogi.radiometry``: band radiance <-> radiometric temperature.

The path the documentation has always given (``from qogi.radiometry import ...``);
the code lives in :mod:`qogi.physics.radiometry`, at its place among the layers.
"""

from .physics.radiometry import *  # noqa: F403
from .physics.radiometry import __all__  # noqa: F401
