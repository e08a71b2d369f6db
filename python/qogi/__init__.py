"""qogi: quantitative optical gas imaging.

Radiometric mid-wave infrared video of a gas plume in, emission rate (kg/h,
with an uncertainty) out. The physics follows Nagorski, "Quantitative Optical
Gas Imaging using Broadband MWIR Single-Channel and Multispectral Cameras"
(University of Waterloo, 2022); equation numbers in docstrings are the thesis's.

The heavy lifting is done by the C++ engine in :mod:`qogi._engine`; this
package is the public API.
"""

from . import (  # noqa: F401  (qogi.io.read_flir etc. after `import qogi`)
    camera,
    inversion,
    io,
    radiometry,
    synth,
    units,
)
from ._version import __version__
from .camera import (
    Calibration,
    CalibrationScene,
    ChannelOptics,
    add_netd_noise,
    add_warm_optics,
    camera_optics,
    correct_warm_optics,
    fit_calibration,
    netd_radiance_sigma,
    warm_optics_radiance,
)
from .forward import ForwardModel, band_radiance, column_density, forward_model
from .inversion import Inversion, InversionResult
from .io.open import open_recording  # HDF5 recordings and camera files (FLIR, Telops)
from .optics import SpectralResponse, planck_radiance, planck_radiance_derivative
from .pipeline import Cancelled, QuantifyConfig, quantify
from .presets import camera_preset, camera_preset_names
from .recording import (
    Camera,
    Recording,
    RecordingError,
    RecordingWriter,
    Scene,
    Truth,
    write_recording,
)
from .result import Result
from .spectra import (
    CrossSectionTable,
    LineList,
    absorption_coefficient,
    cross_section,
    cross_section_table,
    find_line_lists,
    load_line_list,
    partition_sum,
    voigt_profile,
)
from .surfaces import Region, Surface, auto_surfaces, detect_source, plume_image
from .velocimetry import FlowEstimator, optical_flow, optical_flow_sequence

__all__ = [
    "Cancelled",
    "QuantifyConfig",
    "Region",
    "Result",
    "Surface",
    "auto_surfaces",
    "detect_source",
    "plume_image",
    "quantify",
    "__version__",
    "SpectralResponse",
    "planck_radiance",
    "planck_radiance_derivative",
    "camera_preset",
    "camera_preset_names",
    "ForwardModel",
    "band_radiance",
    "column_density",
    "forward_model",
    "Camera",
    "Recording",
    "RecordingError",
    "RecordingWriter",
    "Scene",
    "Truth",
    "open_recording",
    "write_recording",
    "CrossSectionTable",
    "LineList",
    "absorption_coefficient",
    "cross_section",
    "cross_section_table",
    "find_line_lists",
    "load_line_list",
    "partition_sum",
    "voigt_profile",
    "Calibration",
    "CalibrationScene",
    "fit_calibration",
    "netd_radiance_sigma",
    "add_netd_noise",
    "ChannelOptics",
    "camera_optics",
    "warm_optics_radiance",
    "add_warm_optics",
    "correct_warm_optics",
    "FlowEstimator",
    "optical_flow",
    "optical_flow_sequence",
    "synth",
    "Inversion",
    "InversionResult",
]
