"""The forward models' cross-section tables built by the engine from HITRAN
(qogi.physics.forward.build_absorber_tables -> _engine.build_absorber_tables) equal the
tables qogi.physics.spectra's general function builds from the same lines, range rule and
settings, on the GF320 and the four-channel fast-M150 presets."""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi import _engine
from qogi.errors import Cancelled, DataError
from qogi.physics import spectra
from qogi.physics.forward import LineShape, build_absorber_tables

#: A short temperature grid keeps the tables small; the grid in wavenumber (what
#: the range rule decides) is the full one.
TEMPS = [250.0, 300.0, 350.0]

#: (first wavenumber [cm-1], points) of each species' table, frozen from the
#: previous Python path (commit aba9206:
#: `qogi.forward.build_absorber_tables(["CH4", "CO2"],
#: qogi.camera_preset("fast-m150").channels)`
#: and the same for ["CH4"] on "gf320").
FROZEN_GRID = {"CH4": (2807.86, 46345), "CO2": (2075.02, 24998)}


def _reference(species, channels, shape: LineShape):
    """The tables as qogi.physics.spectra builds them: the species' lines, the band of
    the channels narrowed to the lines +- 25 cm-1, its start on a multiple of
    the 0.01 cm-1 step, air and (with self-broadening) pure-gas tables."""
    lines = spectra.load_line_list(species)
    lo = max(min(c.nu_cm1[0] for c in channels), lines.nu_cm1.min() - 25.0)
    hi = min(max(c.nu_cm1[-1] for c in channels), lines.nu_cm1.max() + 25.0)
    lo = np.floor(lo / 0.01) * 0.01
    fractions = [0.0, 1.0] if shape.self_broadening else [0.0]
    return [
        spectra.cross_section_table(
            species, lo, hi, 0.01, TEMPS, self_fraction=x, cutoff=shape.cutoff, cache=False
        )
        for x in fractions
    ]


@pytest.mark.parametrize(
    ("preset", "species", "shape"),
    [
        ("gf320", ["CH4"], "fixed:25+self"),
        ("fast-m150", ["CH4", "CO2"], "fixed:25+self"),
        ("fast-m150", ["CO2"], "hapi+air"),
    ],
)
def test_engine_tables_equal_the_spectra_tables_bit_for_bit(preset, species, shape):
    channels = qogi.camera_preset(preset).channels
    ls = LineShape.parse(shape)
    tables = build_absorber_tables(
        species,
        channels,
        temperatures_K=TEMPS,
        self_broadening=ls.self_broadening,
        cutoff=ls.cutoff,
        cache=False,
    )
    assert [t.species for t in tables] == species
    for t in tables:
        ref = _reference(t.species, channels, ls)
        assert (t.nu0_cm1, t.n_nu) == FROZEN_GRID[t.species]
        assert t.nu0_cm1 == ref[0].nu_cm1[0] and t.dnu_cm1 == ref[0].step_cm1 == 0.01
        assert t.n_nu == len(ref[0].nu_cm1) and t.pressure_Pa == 101325.0
        np.testing.assert_array_equal(t.temperatures_K, TEMPS)
        np.testing.assert_array_equal(t.sigma_air, ref[0].sigma)
        if ls.self_broadening:
            np.testing.assert_array_equal(t.sigma_self, ref[1].sigma)
            assert not np.array_equal(t.sigma_self, t.sigma_air)
        else:
            assert t.sigma_self is None and not t.has_self


def test_cached_tables_are_the_spectra_cache_and_equal_fresh_ones(tmp_path, monkeypatch):
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path))
    channels = [_engine.SpectralResponse(np.array([3050.0, 3052.0]), np.array([1.0, 1.0]))]
    fresh = build_absorber_tables(["CH4"], channels, temperatures_K=TEMPS, cache=False)[0]
    assert not (tmp_path / "xsec").exists()
    stored = build_absorber_tables(["CH4"], channels, temperatures_K=TEMPS)[0]
    files = sorted((tmp_path / "xsec").glob("*.qxs"))
    assert len(files) == 2  # air and pure gas
    stamps = [f.stat().st_mtime_ns for f in files]
    again = build_absorber_tables(["CH4"], channels, temperatures_K=TEMPS)[0]
    assert [f.stat().st_mtime_ns for f in files] == stamps  # read, not rebuilt
    for t in (stored, again):
        np.testing.assert_array_equal(t.sigma_air, fresh.sigma_air)
        np.testing.assert_array_equal(t.sigma_self, fresh.sigma_self)
    # qogi.physics.spectra finds the same files under the same keys.
    lo = max(3050.0, spectra.load_line_list("CH4").nu_cm1.min() - 25.0)
    table = spectra.cross_section_table("CH4", np.floor(lo / 0.01) * 0.01, 3052.0, 0.01, TEMPS)
    assert sorted((tmp_path / "xsec").glob("*.qxs")) == files
    np.testing.assert_array_equal(table.sigma, fresh.sigma_air)


def test_a_species_without_lines_in_the_band_names_it_and_the_fix():
    co2 = qogi.LineList(
        molecule=[2, 2],
        isotopologue=[1, 1],
        nu_cm1=[2300.0, 2349.1],
        intensity=[1e-19, 1e-18],
        gamma_air=[0.07, 0.07],
        gamma_self=[0.09, 0.09],
        elower_cm1=[0.0, 0.0],
        n_air=[0.7, 0.7],
        delta_air=[0.0, 0.0],
    )
    gf320 = qogi.camera_preset("gf320").channels
    with pytest.raises(
        ValueError, match=r"the CO2 line list \(2300.0-2349.1 cm-1\) does not reach"
    ):
        build_absorber_tables(["CO2"], gf320, line_lists={"CO2": co2}, cache=False)
    with pytest.raises(ValueError, match="drop CO2 from the species or give a line list"):
        qogi.ForwardModel(gf320, ["CO2"], line_lists={"CO2": co2})


def test_a_named_line_file_wins_and_a_missing_one_is_named(hitran_dir, tmp_path):
    channels = [_engine.SpectralResponse(np.array([2200.0, 2201.0]), np.array([1.0, 1.0]))]
    with pytest.raises(ValueError, match=r"has no CO2 lines \(molecule code 2\)"):
        build_absorber_tables(
            ["CO2"], channels, line_lists={"CO2": hitran_dir / "CH4.par.gz"}, cache=False
        )
    with pytest.raises(FileNotFoundError, match="line list path not found"):
        build_absorber_tables(
            ["CO2"], channels, line_lists={"CO2": tmp_path / "nowhere.par"}, cache=False
        )
    bad = tmp_path / "CO2.par"
    bad.write_text("not a HITRAN record\n")
    with pytest.raises(DataError, match="160-character record"):
        build_absorber_tables(["CO2"], channels, line_lists={"CO2": bad}, cache=False)


@pytest.mark.parametrize("cache", [False, True])
def test_progress_runs_once_over_all_tables_and_false_cancels(cache, tmp_path, monkeypatch):
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path))
    channels = [_engine.SpectralResponse(np.array([2200.0, 3050.0]), np.array([1.0, 1.0]))]
    seen: list[float] = []
    kw = dict(temperatures_K=TEMPS, step_cm1=0.05, cache=cache)
    build_absorber_tables(["CH4", "CO2"], channels, progress=seen.append, **kw)
    assert seen and seen[-1] == pytest.approx(1.0)
    assert all(b >= a for a, b in zip(seen, seen[1:]))
    assert any(0.2 < f < 0.8 for f in seen)  # one run over the four tables, not four
    with pytest.raises(Cancelled):
        build_absorber_tables(
            ["CH4", "CO2"], channels, progress=lambda f: False, **dict(kw, cache=False)
        )
