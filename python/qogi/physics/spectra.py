"""Absorption cross-sections from HITRAN line lists, and sigma(nu, T) tables.

Units follow HITRAN: wavenumber ``nu_cm1`` in cm-1, line intensity S in
cm-1/(molecule cm-2) = cm/molecule (at 296 K, natural abundance included),
cross-section sigma in cm2/molecule, absorption coefficient in cm-1. Pressures
are in Pa at this interface (1 atm = 101325 Pa), temperatures in K.

Physics (HITRAN conventions; the same as HAPI 1.3's
``absorptionCoefficient_Voigt``), with Tref = 296 K, p in atm, x the
absorber's mole fraction (``self_fraction``), c2 = hc/k_B = 1.4387769 cm K:

* intensity: ``S(T) = S(Tref) Q(Tref)/Q(T) exp(-c2 E''/T)/exp(-c2 E''/Tref)
  (1 - exp(-c2 nu/T))/(1 - exp(-c2 nu/Tref))``, Q from TIPS-2025
  (Gamache et al., JQSRT 345 (2025) 109568);
* Lorentz HWHM: ``gamma_L = p [(1-x) gamma_air (Tref/T)^n_air + x gamma_self
  (Tref/T)^n_self]``; HITRAN .par records carry no n_self, so n_self = n_air
  (as HAPI does);
* line centre: ``nu + p [(1-x) delta_air + x delta_self]``; .par records carry
  no delta_self, so delta_self = delta_air (HAPI would use 0);
* Doppler HWHM: ``gamma_D = nu/c sqrt(2 N_A k_B T ln2 / M)``;
* profile: Voigt, ``V = Re w(x + iy) / (alpha sqrt(pi))``, alpha =
  gamma_D/sqrt(ln 2), w the Faddeeva function (Weideman's N = 32 rational
  approximation, SIAM J. Numer. Anal. 31 (1994) 1497, near the centre;
  Laplace continued-fraction convergents (Humlicek, JQSRT 27 (1982) 437)
  outside); relative error of Re w below 3e-5 over 1e-4 <= y <= 1e3,
  |x| <= 1e4 (measured against scipy.special.wofz);
* ``sigma(nu) = sum_i S_i(T) V_i(nu - nu*_i)`` over lines whose wing window
  ``nu_i - W_i < nu <= nu_i + W_i`` holds nu, ``W_i = max(wing_cm1,
  wing_half_widths max(gamma_L, gamma_D))``.

Line lists are found (see :func:`find_line_lists`) in user paths,
``$QOGI_HITRAN_PATH``, the per-user cache (``$QOGI_CACHE_DIR/hitran``, default
``~/.cache/qogi/hitran``) and, last, the subsets the package ships
(``qogi/data/hitran``: CH4, CO2 and H2O over every preset channel's band, with
their provenance in ``MANIFEST.json``; :func:`bundled_line_lists`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import pathlib
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from typing import Callable, Dict, Iterable, Optional, Sequence, Tuple, Union

import numpy as np

from .. import _engine
from .._version import __version__
from ..cache import cache_dir, cache_path, store
from ..errors import DataError
from ..files import atomic_open

log = logging.getLogger(__name__)

__all__ = [
    "LineList",
    "CrossSectionTable",
    "cross_section",
    "absorption_coefficient",
    "cross_section_table",
    "load_line_list",
    "find_line_lists",
    "hitran_search_path",
    "line_parameters",
    "partition_sum",
    "isotopologues",
    "voigt_profile",
    "faddeeva",
    "cache_dir",
    "bundled_hitran_dir",
    "bundled_line_lists",
    "fetch_hitran",
    "DEFAULT_TABLE_TEMPERATURES_K",
    "DEFAULT_TABLE_CUTOFF_CM1",
]

LineList = _engine.LineList

ATM_PA = 101325.0
#: Temperatures of a table unless given: 200-800 K every 10 K.
DEFAULT_TABLE_TEMPERATURES_K = np.arange(200.0, 800.0 + 1e-9, 10.0)
#: Fixed wing cutoff of tables unless given [cm-1] (see :func:`cross_section_table`).
DEFAULT_TABLE_CUTOFF_CM1 = 25.0
#: Bumped whenever a change in the computation changes cross-sections, so
#: that cached tables made by older code are rebuilt.
SPECTRA_MODEL_VERSION = 1

PathLike = Union[str, os.PathLike]
LineListArg = Union[None, PathLike, Sequence[PathLike], "LineList"]
Cutoff = Union[str, float, tuple]


# ---------------------------------------------------------------------------
# Where things live


def bundled_hitran_dir() -> pathlib.Path:
    """The folder of line-list subsets shipped inside the package."""
    return pathlib.Path(__file__).resolve().parent.parent / "data" / "hitran"


def bundled_line_lists() -> list[dict]:
    """What the package ships: one dict per file (``file``, ``species``,
    ``isotopologues``, ``lines``, ``nu_min_cm1``, ``nu_max_cm1``, ``edition``,
    ``citation``, ``source``, ``sha256_records``, ``sha256_gz``, ``bytes_gz``,
    and ``path``), from ``MANIFEST.json`` beside the files."""
    folder = bundled_hitran_dir()
    manifest = json.loads((folder / "MANIFEST.json").read_text())
    out = []
    for entry in manifest["files"]:
        e = dict(entry)
        e["path"] = folder / entry["file"]
        out.append(e)
    return out


def hitran_search_path(paths: Optional[Iterable[PathLike]] = None) -> list[pathlib.Path]:
    """Folders searched for line lists, in order.

    1. ``paths`` given by the caller;
    2. the folders in ``$QOGI_HITRAN_PATH`` (separated by ``os.pathsep``);
    3. the per-user cache, ``cache_dir() / "hitran"`` (where
       :func:`fetch_hitran` saves);
    4. the subsets shipped with the package (:func:`bundled_hitran_dir`).

    A user's own files therefore always win over the bundled ones.
    """
    folders = [os.fspath(pathlib.Path(p).expanduser()) for p in (paths or [])]
    return [pathlib.Path(p) for p in _engine.line_search_path(folders, _fallback_folders())]


def _fallback_folders() -> list[str]:
    """The folders searched after the caller's and ``$QOGI_HITRAN_PATH``: the
    per-user download cache, then the bundled subsets."""
    return [os.fspath(cache_dir() / "hitran"), os.fspath(bundled_hitran_dir())]


def find_line_lists(species: str, paths: Optional[Iterable[PathLike]] = None) -> list[pathlib.Path]:
    """Line files of a species, highest priority first.

    Folders are searched in the order of :func:`hitran_search_path`; the first
    folder that holds any file of the species wins (a folder you name hides the
    ones after it). In that folder, files are matched case-insensitively:
    ``<SPECIES>.par``, ``.data``, ``.par.gz`` or ``.data.gz`` first, then
    ``<SPECIES>_*``/``<SPECIES>-*`` files in name order. All of them are used
    and merged so that no transition counts twice: a file's lines are dropped
    where a higher-priority file covers the same isotopologue at that
    wavenumber (e.g. ``H2O.par``, HITRAN2020 main isotopologue over 2000-5000
    cm-1, plus ``H2O_HITRAN2012_all.par.gz`` for the other isotopologues and
    outside that span).

    ``paths`` may also name files directly; those are returned as given.

    Raises
    ------
    FileNotFoundError
        Naming every folder searched and how to provide line lists.
    """
    given = [os.fspath(pathlib.Path(p).expanduser()) for p in (paths or [])]
    return [pathlib.Path(f) for f in _engine.find_line_files(species, given, _fallback_folders())]


# ---------------------------------------------------------------------------
# Line lists

_cache_lock = threading.Lock()
_loaded: Dict[tuple, _Loaded] = {}  # (file signature, molecule) -> lines read


def _file_signature(files: Sequence[pathlib.Path]) -> tuple:
    sig = []
    for f in files:
        st = os.stat(f)
        sig.append((str(pathlib.Path(f).resolve()), st.st_size, st.st_mtime_ns))
    return tuple(sig)


def _molecule(species: Union[str, int]) -> int:
    if isinstance(species, (int, np.integer)):
        _engine.molecule_formula(int(species))
        return int(species)
    return _engine.molecule_id(str(species))


def line_list_digest(lines: LineList) -> str:
    """SHA-256 of a line list's content (every array the physics uses)."""
    h = hashlib.sha256()
    for name in (
        "molecule",
        "isotopologue",
        "nu_cm1",
        "intensity",
        "gamma_air",
        "gamma_self",
        "elower_cm1",
        "n_air",
        "n_self",
        "delta_air",
        "delta_self",
    ):
        a = np.ascontiguousarray(getattr(lines, name))
        h.update(name.encode())
        h.update(str(a.dtype).encode())
        h.update(a.tobytes())
    return h.hexdigest()


class _Loaded:
    """A line list read from files, with its content digest computed on demand."""

    def __init__(self, lines: LineList, sources):
        self.lines = lines
        self.sources = sources
        self._digest: Optional[str] = None

    @property
    def digest(self) -> str:
        if self._digest is None:
            self._digest = line_list_digest(self.lines)
        return self._digest


def malformed_line_file(error: RuntimeError) -> DataError:
    """The error for a line file the engine could not parse (its message names
    the file, line, field and columns), with what the format needs."""
    return DataError(
        f"{error}. A HITRAN .par line list has one 160-character record per line "
        "(HITRAN2004 and later; a HAPI .data file with extra parameters needs its "
        ".header beside it): re-download the file (`qogi hitran fetch`), or remove "
        "it from the line-list path"
    )


def _read(files: Sequence[pathlib.Path], molecule: int) -> _Loaded:
    key = (_file_signature(files), molecule)
    with _cache_lock:
        hit = _loaded.get(key)
    if hit is not None:
        return hit
    try:
        lines = _engine.read_molecule_lines([os.fspath(f) for f in files], molecule)
    except RuntimeError as e:  # the engine names the file, line, field and columns
        raise malformed_line_file(e) from None
    entry = _Loaded(lines, [os.fspath(f) for f in files])
    with _cache_lock:
        if len(_loaded) > 16:
            _loaded.clear()
        _loaded[key] = entry
    return entry


def _resolve(species: Union[str, int, None], line_list: LineListArg) -> _Loaded:
    """The line list for a species and a ``line_list`` argument."""
    if isinstance(line_list, _engine.LineList):
        lines = line_list
        if species is not None:
            mol = _molecule(species)
            if np.any(lines.molecule != mol):
                lines = lines.select(molecule=mol)
        return _Loaded(lines, ["<LineList>"])
    if species is None:
        raise ValueError("species is required unless line_list is a LineList")
    mol = _molecule(species)
    formula = _engine.molecule_formula(mol)
    if line_list is None:
        files = find_line_lists(formula)
    elif isinstance(line_list, (str, os.PathLike)):
        files = find_line_lists(formula, [line_list])
    else:
        files = find_line_lists(formula, list(line_list))
    return _read(files, mol)


def load_line_list(
    species: Union[str, int, None] = None,
    line_list: LineListArg = None,
    *,
    nu_min_cm1: float = 0.0,
    nu_max_cm1: float = np.inf,
    isotopologues: Optional[Sequence[int]] = None,
    min_intensity: float = 0.0,
) -> LineList:
    """Read (and merge) the HITRAN lines of a species.

    Parameters
    ----------
    species : str or int
        Formula (``"CH4"``) or HITRAN molecule code (6). Lines of other
        molecules in the files are left out.
    line_list : None, path, list of paths or LineList
        None searches the usual places (:func:`find_line_lists`); a folder is
        searched for the species' files; files are used in the order given
        (first = highest priority when they overlap).
    nu_min_cm1, nu_max_cm1 : float, cm-1
        Keep lines with ``nu_min_cm1 <= nu <= nu_max_cm1``.
    isotopologues : list of int, optional
        HITRAN local isotopologue numbers to keep (1 = most abundant).
    min_intensity : float, cm/molecule
        Keep lines with S(296 K) >= min_intensity.

    Returns
    -------
    LineList
        Arrays ``molecule, isotopologue, nu_cm1, intensity, einstein_a,
        gamma_air, gamma_self, elower_cm1, n_air, n_self, delta_air,
        delta_self`` plus ``sources`` and ``coverage``; sorted by wavenumber.

    Raises
    ------
    FileNotFoundError
        No line list found (the message lists where it looked).
    qogi.errors.DataError
        A malformed record or an unreadable file (file, line number, field
        and columns named, and what the format needs).
    """
    lines = _resolve(species, line_list).lines
    if nu_min_cm1 > 0 or np.isfinite(nu_max_cm1) or isotopologues or min_intensity > 0:
        lines = lines.select(
            nu_min_cm1=float(nu_min_cm1),
            nu_max_cm1=float(nu_max_cm1),
            isotopologues=list(isotopologues or []),
            min_intensity=float(min_intensity),
        )
    return lines


# ---------------------------------------------------------------------------
# Small physics helpers


def isotopologues() -> list[dict]:
    """Isotopologues qogi has data for: HITRAN molar mass [g/mol], natural
    abundance, TIPS-2025 Q(296 K) and its temperature range."""
    return _engine.isotopologues()


def partition_sum(species: Union[str, int], temperature_K, isotopologue: int = 1):
    """Total internal partition sum Q(T) (TIPS-2025, 4-point Lagrange in T).

    Raises ValueError for an isotopologue without data or T outside its table.
    """
    t = np.asarray(temperature_K, dtype=float)
    out = _engine.partition_sum(_molecule(species), int(isotopologue), t.ravel()).reshape(t.shape)
    return float(out) if out.ndim == 0 else out


def faddeeva(x, y):
    """Faddeeva function w(x + iy) = exp(-z^2) erfc(-iz) for y >= 0 (complex).

    Accuracy of the real part (the Voigt function) better than 3e-5 relative
    over 1e-4 <= y <= 1e3, |x| <= 1e4 (see module docstring).
    """
    x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
    out = _engine.faddeeva(np.ascontiguousarray(x).ravel(), np.ascontiguousarray(y).ravel())
    out = out.reshape(x.shape)
    return complex(out) if out.ndim == 0 else out


def voigt_profile(dnu_cm1, gamma_doppler_cm1: float, gamma_lorentz_cm1: float):
    """Area-normalised Voigt profile [cm] at ``dnu_cm1`` from the line centre,
    for Doppler and Lorentz half-widths at half maximum [cm-1]."""
    d = np.asarray(dnu_cm1, dtype=float)
    out = _engine.voigt_profile(
        d.ravel(), float(gamma_doppler_cm1), float(gamma_lorentz_cm1)
    ).reshape(d.shape)
    return float(out) if out.ndim == 0 else out


def _options(cutoff: Cutoff, line_shift: bool, min_intensity: float):
    """CrossSectionOptions from the public ``cutoff`` argument."""
    if isinstance(cutoff, str):
        if cutoff.lower() != "hapi":
            raise ValueError(
                f"cutoff must be 'hapi', a number of cm-1, or ('half_widths', k); got {cutoff!r}"
            )
        return _engine.CrossSectionOptions(
            wing_half_widths=50.0, wing_cm1=0.0, line_shift=line_shift, min_intensity=min_intensity
        )
    if isinstance(cutoff, tuple):
        if len(cutoff) != 2 or cutoff[0] != "half_widths":
            raise ValueError(f"cutoff tuple must be ('half_widths', k); got {cutoff!r}")
        return _engine.CrossSectionOptions(
            wing_half_widths=float(cutoff[1]),
            wing_cm1=0.0,
            line_shift=line_shift,
            min_intensity=min_intensity,
        )
    c = float(cutoff)
    if not (np.isfinite(c) and c > 0):
        raise ValueError(f"cutoff in cm-1 must be finite and > 0; got {cutoff!r}")
    return _engine.CrossSectionOptions(
        wing_half_widths=0.0, wing_cm1=c, line_shift=line_shift, min_intensity=min_intensity
    )


def line_parameters(
    species: Union[str, int, None],
    temperature_K: float,
    pressure_Pa: float = ATM_PA,
    self_fraction: float = 0.0,
    line_list: LineListArg = None,
    line_shift: bool = True,
) -> dict:
    """Per-line ``nu_cm1``, shifted ``center_cm1``, ``intensity`` S(T)
    [cm/molecule], ``gamma_lorentz`` and ``gamma_doppler`` HWHM [cm-1] at the
    given conditions (equations in the module docstring)."""
    lines = _resolve(species, line_list).lines
    cond = _engine.GasConditions(float(temperature_K), float(pressure_Pa), float(self_fraction))
    return _engine.line_parameters(lines, cond, line_shift)


# ---------------------------------------------------------------------------
# Cross-sections


def _uniform(nu: np.ndarray) -> Optional[Tuple[float, float, int]]:
    """(nu0, step, n) when nu is a uniform grid to 1e-9 of its step."""
    if nu.size < 2:
        return None
    step = (nu[-1] - nu[0]) / (nu.size - 1)
    if not step > 0:
        return None
    ideal = nu[0] + step * np.arange(nu.size)
    if np.max(np.abs(nu - ideal)) <= 1e-9 * step:
        return float(nu[0]), float(step), int(nu.size)
    return None


def cross_section(
    species: Union[str, int, None],
    nu_cm1,
    temperature_K: float,
    pressure_Pa: float = ATM_PA,
    line_list: LineListArg = None,
    cutoff: Cutoff = "hapi",
    self_fraction: float = 0.0,
    *,
    line_shift: bool = True,
    min_intensity: float = 0.0,
    num_threads: int = 0,
    progress: Optional[Callable[[float], Optional[bool]]] = None,
):
    """Absorption cross-section sigma(nu) of a gas [cm2/molecule].

    A sum of Voigt lines (module docstring) with HITRAN line parameters scaled
    to ``temperature_K``, ``pressure_Pa`` and the absorber's mole fraction
    ``self_fraction`` (self-broadening).

    Parameters
    ----------
    species : str or int
        ``"CH4"``, ``"CO2"``, ``"H2O"`` ... or a HITRAN molecule code.
    nu_cm1 : float or array, cm-1
        Wavenumbers, strictly increasing (any spacing; a uniform grid is
        detected and computed faster).
    temperature_K : float, K
        Gas temperature, within the TIPS range of every isotopologue in the
        list (e.g. 1-2500 K for CH4).
    pressure_Pa : float, Pa, default 101325
        Total pressure.
    line_list : None, path, list of paths or LineList
        Where the lines come from (see :func:`load_line_list`).
    cutoff : 'hapi', float or ('half_widths', k), default 'hapi'
        Line wings: ``'hapi'`` is HAPI 1.3's rule, each line computed within
        50 x max(gamma_L, gamma_D) of its unshifted position; a number C gives
        a fixed window of +-C cm-1; ``('half_widths', k)`` k half-widths.
    self_fraction : float in [0, 1], default 0
        Absorber mole fraction used for self-broadening and self-shift (0 = a
        trace gas in air).
    line_shift : bool, default True
        Apply the pressure shift.
    min_intensity : float, cm/molecule, default 0
        Skip lines whose S(T) is below this (HAPI's IntensityThreshold).
    num_threads : int, default 0 (all cores)
    progress : callable, optional
        ``progress(fraction)``; return False to cancel.

    Returns
    -------
    float or ndarray
        sigma [cm2/molecule], shaped like ``nu_cm1``.

    Examples
    --------
    >>> nu = np.arange(2900.0, 3100.0, 0.01)
    >>> sigma = cross_section("CH4", nu, 296.0)            # doctest: +SKIP
    """
    lines = _resolve(species, line_list).lines
    nu = np.asarray(nu_cm1, dtype=float)
    flat = np.ascontiguousarray(nu.ravel())
    cond = _engine.GasConditions(float(temperature_K), float(pressure_Pa), float(self_fraction))
    opt = _options(cutoff, line_shift, float(min_intensity))
    uniform = _uniform(flat)
    if uniform is not None:
        nu0, step, size = uniform
        out = _engine.cross_section_uniform(
            lines, cond, nu0, step, size, opt, num_threads, progress
        )
    else:
        out = _engine.cross_section_grid(lines, cond, flat, opt, num_threads, progress)
    out = out.reshape(nu.shape)
    return float(out) if out.ndim == 0 else out


def absorption_coefficient(
    species: Union[str, int, None],
    nu_cm1,
    temperature_K: float,
    pressure_Pa: float = ATM_PA,
    mole_fraction: float = 1.0,
    line_list: LineListArg = None,
    cutoff: Cutoff = "hapi",
    **kwargs,
):
    """Absorption coefficient k(nu) = sigma(nu) x n [cm-1] of the gas at mole
    fraction ``mole_fraction`` in a mixture at ``pressure_Pa`` and
    ``temperature_K``; n = x p / (k_B T) is its number density [molecule/cm3].
    The mole fraction is also the self fraction of the broadening. Other
    keyword arguments as for :func:`cross_section`."""
    sigma = cross_section(
        species,
        nu_cm1,
        temperature_K,
        pressure_Pa,
        line_list,
        cutoff,
        self_fraction=mole_fraction,
        **kwargs,
    )
    n = mole_fraction * _engine.number_density_cm3(float(pressure_Pa), float(temperature_K))
    return sigma * n


# ---------------------------------------------------------------------------
# Tables


class CrossSectionTable:
    """sigma(nu, T) on a uniform wavenumber grid x an ascending temperature
    grid, at one pressure and self fraction.

    Attributes
    ----------
    nu_cm1 : ndarray, cm-1
        The wavenumber grid.
    temperatures_K : ndarray, K
        The temperature grid.
    sigma : ndarray, float32 (nT, nnu), cm2/molecule
        The stored cross-sections (read-only view of the engine's table).
    pressure_Pa, self_fraction : float
    engine : qogi._engine.XsecTable
        The C++ table, to hand to other engine code (the forward model).
    metadata : dict
        What the table was built from (species, line files, settings, key).

    Notes
    -----
    Between grid temperatures, ln sigma is interpolated with a cubic (4-point
    Lagrange) in T; where any of the 4 values is 0, sigma is interpolated
    linearly between the 2 bracketing temperatures. On the default 10 K grid the
    error against direct computation where sigma > 1% of its maximum is ~5e-5
    for CH4 and CO2 and 4e-4 for H2O in the CH4 window (docs/spectroscopy.md).
    """

    def __init__(self, engine_table: _engine.XsecTable):
        self.engine = engine_table

    @property
    def nu_cm1(self) -> np.ndarray:
        t = self.engine
        return t.nu0_cm1 + t.step_cm1 * np.arange(t.num_wavenumbers)

    @property
    def step_cm1(self) -> float:
        return self.engine.step_cm1

    @property
    def temperatures_K(self) -> np.ndarray:
        return self.engine.temperatures_K

    @property
    def sigma(self) -> np.ndarray:
        return self.engine.sigma

    @property
    def pressure_Pa(self) -> float:
        return self.engine.pressure_Pa

    @property
    def self_fraction(self) -> float:
        return self.engine.self_fraction

    @property
    def options(self):
        return self.engine.options

    @property
    def metadata(self) -> dict:
        text = self.engine.metadata
        return json.loads(text) if text else {}

    def interpolate(self, temperature_K):
        """sigma at temperature(s) [cm2/molecule]: shape (nnu,) for a scalar,
        (len(T), nnu) for an array. Raises ValueError outside the grid."""
        t = np.asarray(temperature_K, dtype=float)
        if t.ndim == 0:
            return self.engine.spectrum(float(t))
        return np.stack([self.engine.spectrum(float(v)) for v in t.ravel()]).reshape(
            t.shape + (self.engine.num_wavenumbers,)
        )

    def derivative(self, temperature_K: float) -> np.ndarray:
        """d sigma / dT of the interpolant [cm2/(molecule K)] at one temperature."""
        return self.engine.spectrum(float(temperature_K), derivative=True)[1]

    def save(self, path: PathLike) -> None:
        """Write the table (qogi table format, see XsecTable.save)."""
        self.engine.save(os.fspath(path))

    @classmethod
    def load(cls, path: PathLike) -> CrossSectionTable:
        """Read a table written by :meth:`save`."""
        return cls(_engine.XsecTable.load(os.fspath(path)))

    def __repr__(self) -> str:
        nu = self.nu_cm1
        m = self.metadata
        return (
            f"CrossSectionTable({m.get('species', '?')}, {nu[0]:.2f}-{nu[-1]:.2f} cm-1 "
            f"step {self.step_cm1:g}, T {self.temperatures_K[0]:g}-"
            f"{self.temperatures_K[-1]:g} K ({len(self.temperatures_K)}), "
            f"p {self.pressure_Pa:g} Pa, self fraction {self.self_fraction:g})"
        )


def _table_key(
    digest: str,
    formula: str,
    grid: tuple,
    temps: np.ndarray,
    pressure: float,
    self_fraction: float,
    opt,
) -> str:
    h = hashlib.sha256()
    settings = {
        "format": int(_engine.XSEC_TABLE_FORMAT_VERSION),
        "model": SPECTRA_MODEL_VERSION,
        "species": formula,
        "line_list": digest,
        "grid": [repr(float(grid[0])), repr(float(grid[1])), int(grid[2])],
        "pressure_Pa": repr(float(pressure)),
        "self_fraction": repr(float(self_fraction)),
        "options": {k: (repr(v) if isinstance(v, float) else v) for k, v in opt.to_dict().items()},
    }
    h.update(json.dumps(settings, sort_keys=True).encode())
    h.update(np.ascontiguousarray(temps, dtype=np.float64).tobytes())
    return h.hexdigest()


def cross_section_table(
    species: Union[str, int, None],
    nu_min_cm1: float,
    nu_max_cm1: float,
    step_cm1: float = 0.01,
    temperatures_K=None,
    pressure_Pa: float = ATM_PA,
    self_fraction: float = 0.0,
    line_list: LineListArg = None,
    cache: bool = True,
    cutoff: Cutoff = DEFAULT_TABLE_CUTOFF_CM1,
    *,
    line_shift: bool = True,
    min_intensity: float = 0.0,
    num_threads: int = 0,
    progress: Optional[Callable[[float], Optional[bool]]] = None,
) -> CrossSectionTable:
    """Cross-section table sigma(nu, T) for the forward model (cached on disk).

    Parameters
    ----------
    species : str or int
        ``"CH4"``, ``"CO2"``, ``"H2O"`` ... or a HITRAN molecule code.
    nu_min_cm1, nu_max_cm1, step_cm1 : float, cm-1
        The grid, as HAPI builds it: ``nu_min + j step`` up to ``nu_max``.
    temperatures_K : array, K, default 200-800 K every 10 K
        Strictly increasing temperatures.
    pressure_Pa : float, Pa, default 101325
    self_fraction : float in [0, 1], default 0
        Absorber mole fraction for self-broadening.
    line_list : as for :func:`cross_section`.
    cache : bool, default True
        Reuse a table from the cache folder (``cache_dir() / "xsec"``) whose
        key matches, else build and store it. The key is a SHA-256 of the line
        list's content and every setting that changes the output (species,
        grid, temperatures, pressure, self fraction, wing rule, line shift,
        intensity threshold, file format and model versions). A cached file
        that fails to load (corrupt, truncated, other format version) or whose
        key differs is rebuilt.
    cutoff : float, 'hapi' or ('half_widths', k), default 25 cm-1
        Line wings (see :func:`cross_section`). Tables default to a fixed 25
        cm-1 window: HAPI's 50-half-width rule moves each window edge with the
        temperature-dependent line width, so sigma(T) at a fixed nu jumps by up
        to ~1% where a strong line's window ends, which no interpolation in T
        can follow; a fixed window keeps sigma smooth in T (and keeps more of
        the line wings: 50 half-widths drop ~1.3% of each Lorentz line's area).
    line_shift, min_intensity, num_threads, progress : as for :func:`cross_section`.

    Returns
    -------
    CrossSectionTable
    """
    entry = _resolve(species, line_list)
    formula = _engine.molecule_formula(_molecule(species)) if species is not None else "mixed"
    grid = _engine.grid_from_range(float(nu_min_cm1), float(nu_max_cm1), float(step_cm1))
    temps = (
        DEFAULT_TABLE_TEMPERATURES_K
        if temperatures_K is None
        else np.asarray(temperatures_K, dtype=float).ravel()
    )
    opt = _options(cutoff, line_shift, float(min_intensity))
    return _cached_table(
        entry,
        formula,
        grid,
        temps,
        float(pressure_Pa),
        float(self_fraction),
        opt,
        cutoff,
        cache,
        num_threads,
        progress,
    )


def _cached_table(
    entry: _Loaded,
    formula: str,
    grid: tuple,
    temps: np.ndarray,
    pressure_Pa: float,
    self_fraction: float,
    opt,
    cutoff: Cutoff,
    cache: bool,
    num_threads: int,
    progress,
) -> CrossSectionTable:
    """A table from the disk cache when one with its key is there, else built
    by the engine (and stored when ``cache``)."""
    lines, digest, sources = entry.lines, entry.digest, entry.sources
    key = _table_key(digest, formula, grid, temps, pressure_Pa, self_fraction, opt)
    stem = f"{formula}_{grid[0]:g}-{grid[0] + grid[1] * (grid[2] - 1):g}_{key[:20]}"
    path = cache_path("xsec", stem, _xsec_cache_version(), ".qxs")
    if cache and path.is_file():
        try:
            table = _engine.XsecTable.load(os.fspath(path))
            if json.loads(table.metadata or "{}").get("key") == key:
                return CrossSectionTable(table)
            log.info("cached table %s has another key; rebuilding", path)
        except (RuntimeError, ValueError) as e:
            log.warning("cached table %s is unusable (%s); rebuilding", path, e)
    t0 = time.perf_counter()
    table = _engine.XsecTable.build(
        lines,
        grid[0],
        grid[1],
        grid[2],
        temps,
        pressure_Pa,
        self_fraction,
        opt,
        num_threads,
        progress,
    )
    meta = {
        "key": key,
        "species": formula,
        "line_list_sha256": digest,
        "sources": sources,
        "lines": len(lines),
        "cutoff": cutoff if not isinstance(cutoff, tuple) else list(cutoff),
        "options": opt.to_dict(),
        "qogi_version": __version__,
        "model_version": SPECTRA_MODEL_VERSION,
        "build_seconds": round(time.perf_counter() - t0, 3),
    }
    table.metadata = json.dumps(meta)
    if cache:
        store(path, lambda tmp: table.save(str(tmp)))
    return CrossSectionTable(table)


def cached_table_maker(cutoff: Cutoff, num_threads: int = 0) -> Callable:
    """The ``make`` hook of ``_engine.build_absorber_tables``: each table the
    engine asks for comes from the disk cache (as :func:`cross_section_table`
    keeps it) or is built and stored. ``cutoff`` is recorded in the tables'
    metadata."""

    def make(species, lines, nu0, step, size, temps, pressure, self_fraction, opt, progress):
        entry = _Loaded(lines, list(lines.sources) or ["<LineList>"])
        formula = _engine.molecule_formula(_molecule(species))
        temps = np.asarray(temps, dtype=float)
        grid = (nu0, step, size)
        table = _cached_table(
            entry,
            formula,
            grid,
            temps,
            pressure,
            self_fraction,
            opt,
            cutoff,
            True,
            num_threads,
            progress,
        )
        return table.engine

    return make


def _xsec_cache_version() -> str:
    """A cached table's format version: the engine's file format and the
    spectral model's version (either changes what the file means)."""
    return f"{int(_engine.XSEC_TABLE_FORMAT_VERSION)}-{SPECTRA_MODEL_VERSION}"


# ---------------------------------------------------------------------------
# HITRANonline

HITRAN_API_URL = "https://hitran.org/lbl/api"


def _urlopen(url: str, timeout: float):
    return urllib.request.urlopen(url, timeout=timeout)


def fetch_hitran(
    species: Union[str, int],
    nu_min_cm1: float,
    nu_max_cm1: float,
    isotopologues: Optional[Sequence[int]] = None,
    folder: Optional[PathLike] = None,
    timeout_s: float = 120.0,
) -> pathlib.Path:
    """Download HITRAN lines of a species and range from HITRANonline.

    Uses the HITRANonline line-by-line API that HAPI 1.3's ``fetch`` uses
    (``/lbl/api?iso_ids_list=...&numin=...&numax=...``, 160-character .par
    records) and saves ``<SPECIES>_<min>-<max>.par`` in ``folder`` (default:
    the per-user cache, ``cache_dir() / "hitran"``, which :func:`find_line_lists`
    searches). The download is parsed before it is saved. Needs the internet.

    Parameters
    ----------
    isotopologues : list of int, optional
        HITRAN local isotopologue numbers; default all that qogi has partition
        sums for.

    Raises
    ------
    ConnectionError
        HITRANonline unreachable or refusing the request.
    RuntimeError
        The reply is not a valid HITRAN line list.
    """
    mol = _molecule(species)
    formula = _engine.molecule_formula(mol)
    if not (0 <= nu_min_cm1 < nu_max_cm1):
        raise ValueError(f"need 0 <= nu_min_cm1 < nu_max_cm1; got {nu_min_cm1}, {nu_max_cm1}")
    known = {i["local_id"]: i["global_id"] for i in _engine.isotopologues() if i["molecule"] == mol}
    wanted = list(isotopologues) if isotopologues else sorted(known)
    missing = [i for i in wanted if i not in known]
    if missing or not wanted:
        raise ValueError(
            f"{formula}: no data for isotopologues {missing or wanted}; known: {sorted(known)}"
        )
    query = urllib.parse.urlencode(
        {
            "iso_ids_list": ",".join(str(known[i]) for i in wanted),
            "numin": f"{nu_min_cm1:g}",
            "numax": f"{nu_max_cm1:g}",
        },
        safe=",",
    )
    url = f"{HITRAN_API_URL}?{query}"
    try:
        with _urlopen(url, timeout_s) as reply:
            data = reply.read()
    except urllib.error.HTTPError as e:
        raise ConnectionError(f"HITRANonline refused {url}: HTTP {e.code} {e.reason}") from e
    except (urllib.error.URLError, OSError) as e:
        raise ConnectionError(f"cannot reach HITRANonline ({url}): {e}") from e
    folder = pathlib.Path(folder) if folder is not None else cache_dir() / "hitran"
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / f"{formula}_{nu_min_cm1:g}-{nu_max_cm1:g}.par"

    with atomic_open(target, "wb") as fh:
        fh.write(data)
        fh.flush()
        lines = _engine.read_line_files([fh.name])
        if len(lines) == 0:
            raise ConnectionError(
                f"HITRANonline returned no {formula} lines for "
                f"{nu_min_cm1:g}-{nu_max_cm1:g} cm-1 ({url})"
            )
    return target
