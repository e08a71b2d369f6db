"""The synthetic layer: gas releases with exact ground truth (:mod:`.plume`:
Lagrangian puffs on an integral buoyant-jet model), structured backgrounds
(:mod:`.backdrop`) and the synthetic camera that renders them into
recordings (:mod:`.render`). Above physics and io, below the pipeline (whose
hot-gas check uses the plume-rise model).

``qogi.synth`` holds :mod:`.plume`'s public names, as it always has.
"""

from .plume import *  # noqa: F403
from .plume import __all__  # noqa: F401
