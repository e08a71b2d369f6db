"""qogi: quantitative optical gas imaging.

Radiometric mid-wave infrared video of a gas plume in, emission rate (kg/h,
with an uncertainty) out. The physics follows Nagorski, "Quantitative Optical
Gas Imaging using Broadband MWIR Single-Channel and Multispectral Cameras"
(University of Waterloo, 2022); equation numbers in docstrings are the thesis's.

The heavy lifting is done by the C++ engine in :mod:`qogi._engine`; this
package is the public API.
"""

from ._version import __version__
from .optics import SpectralResponse, planck_radiance, planck_radiance_derivative
from . import synth

__all__ = [
    "__version__",
    "SpectralResponse",
    "planck_radiance",
    "planck_radiance_derivative",
    "synth",
]
