"""The quantification pipeline: a recording in, emission-rate time series out.

A chain of stages passing one typed run state forward (docs/pipeline_api.md):

1. **Recording** (:mod:`.setup`): checks, scene constants, timebase, the
   surfaces' samples.
   Then the alignment (:mod:`.align`): frames of a vibrating camera
   resampled to the static scene, a filter wheel's channels brought to the
   turn's time (each only when measured to matter).
2. **Background** (:mod:`.background`): the gas-free band radiance of each
   channel, beside each control surface or a temporal percentile (chosen from
   the scene by default), or from a user region.
3. **Column density** (:mod:`.columns`): the contrast ``L - L_bg`` inverted
   per pixel (:mod:`qogi.inversion`), single channel with the gas temperature
   given or ambient, or several channels with it inferred on the mixing line;
   a fast column proxy for the velocity field around the surfaces.
4. **Velocity** (:mod:`.velocity`): velocimetry on the column field
   (default: the continuity-equation "fluid" flow with the transport's flux
   level), or a given wind / exit speed.
5. **Flux** (:mod:`.flux`, thesis eq. 12): ``F = sum_k c_k (v_k . n_k) dl_k``
   along each surface, per frame and species.
6. **Rate and uncertainty** (:mod:`.budget`): the mean of the per-frame
   rates with a 90 % interval (temporal, column density, velocity, line
   shape, background terms) and the checks in ``Result.warnings``.

Stages 3-5 run block by block (:mod:`qogi.pipeline.timebase`); :func:`quantify`
(:mod:`.run`) chains them. Settings: :class:`QuantifyConfig`
(:mod:`.config`); the state: :mod:`.state`. A stage imports only the stages
before it (tests/python/test_pipeline_layers.py).

See docs/pipeline_api.md for the public contract and docs/validation.md for
the measured accuracy.
"""

from __future__ import annotations

from ..errors import Cancelled
from .budget import COLUMN_SYSTEMATIC, COLUMN_SYSTEMATIC_INFERRED, VELOCITY_SYSTEMATIC
from .config import Execution, Methods, QuantifyConfig, Record, SceneConditions
from .run import BLOCK_BYTES, MIN_BLOCK_FRAMES, quantify
from .setup import check_inputs

#: The call's own checks (surfaces inside the image, channels for an
#: inferred temperature, truth maps, frames, background region), before any
#: work; the command line runs them before its progress bar.
_check_inputs = check_inputs

__all__ = [
    "QuantifyConfig",
    "SceneConditions",
    "Methods",
    "Execution",
    "Record",
    "quantify",
    "Cancelled",
    "VELOCITY_SYSTEMATIC",
    "COLUMN_SYSTEMATIC",
    "COLUMN_SYSTEMATIC_INFERRED",
    "BLOCK_BYTES",
    "MIN_BLOCK_FRAMES",
    "check_inputs",
]
