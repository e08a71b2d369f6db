"""qogi: quantitative optical gas imaging.

Radiometric mid-wave infrared video of a gas plume in, emission rate (kg/h,
with an uncertainty) out. The physics follows Nagorski, "Quantitative Optical
Gas Imaging using Broadband MWIR Single-Channel and Multispectral Cameras"
(University of Waterloo, 2022); equation numbers in docstrings are the thesis's.

The heavy lifting is done by the C++ engine in :mod:`qogi._engine`; this
package is the public API.

The public names load on first use (PEP 562): ``import qogi`` itself is
instant, so the command line (``qogi.apps.cli``) starts without the engine and a
Ctrl-C while the modules load is its own "interrupted", not a traceback.
"""

import functools
import importlib
from typing import TYPE_CHECKING, Any, Dict

from ._version import __version__


@functools.cache  # read on first use: `import qogi` parses nothing
def _lazy_names() -> Dict[str, str]:
    """Public name -> the module (relative to qogi) that defines it, read from
    the ``TYPE_CHECKING`` imports at the end of this file (the one list of the
    names, as lazy_loader's ``attach_stub`` reads a stub), and the submodules
    ``import qogi`` has always made attributes (``qogi.io.read_flir``), which
    map to themselves."""
    import ast

    with open(__file__, encoding="utf-8") as fh:
        tree = ast.parse(fh.read())
    [block] = [
        n
        for n in tree.body
        if isinstance(n, ast.If) and getattr(n.test, "id", "") == "TYPE_CHECKING"
    ]
    out: Dict[str, str] = {}
    for node in block.body:
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                out[alias.name] = "." + (node.module or alias.name)
    return out


def __getattr__(name: str) -> Any:
    where = _lazy_names().get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = importlib.import_module(where, __name__)
    value = module if where == "." + name else getattr(module, name)
    globals()[name] = value  # the next access is a plain attribute
    return value


def __dir__():
    return sorted(set(globals()) | set(_lazy_names()))


if TYPE_CHECKING:  # what the names are, for mypy and editors
    from . import (  # noqa: F401  (qogi.io.read_flir etc. after `import qogi`)
        camera,
        inversion,
        io,
        radiometry,
        synth,
        units,
    )
    from .apps.detectability import PodCurve, PodScene, min_detectable_column_map, pod
    from .contract import RecordingError
    from .io.hdf5_writer import RecordingWriter
    from .io.open import open_recording  # HDF5 recordings and camera files (FLIR, Telops)
    from .io.recording import Recording, Scene, Truth, write_recording
    from .measure.inversion import Inversion, InversionResult
    from .measure.velocimetry import FlowEstimator, optical_flow, optical_flow_sequence
    from .physics.camera import (
        Calibration,
        CalibrationScene,
        Camera,
        ChannelOptics,
        add_netd_noise,
        add_warm_optics,
        camera_optics,
        correct_warm_optics,
        fit_calibration,
        netd_radiance_sigma,
        warm_optics_radiance,
    )
    from .physics.forward import ForwardModel, band_radiance, column_density, forward_model
    from .physics.optics import SpectralResponse, planck_radiance, planck_radiance_derivative
    from .physics.presets import camera_preset, camera_preset_names
    from .physics.spectra import (
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
    from .pipeline import Cancelled, QuantifyConfig, quantify
    from .pipeline.result import Result
    from .pipeline.surfaces import Region, Surface, auto_surfaces, detect_source, plume_image

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
    "pod",
    "PodScene",
    "PodCurve",
    "min_detectable_column_map",
]
