"""Spectroscopy: agreement with HAPI, the Voigt function against scipy, table
interpolation against direct computation, the on-disk cache, the line-list
finder, and the CLI."""

from __future__ import annotations

import gzip
import hashlib
import json
import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest
from scipy.special import wofz

import qogi
from qogi import _engine
from qogi.errors import DataError
from qogi.physics import spectra

DATA = pathlib.Path(__file__).resolve().parents[1] / "data"


def read_par_lines(path: pathlib.Path) -> list:
    """The text records of a (possibly gzip-compressed) HITRAN .par file."""
    raw = path.read_bytes()
    if path.suffix == ".gz":
        raw = gzip.decompress(raw)
    return raw.decode().splitlines(keepends=True)


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Every test gets its own cache folder and no inherited search path."""
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("QOGI_HITRAN_PATH", raising=False)


# ---------------------------------------------------------------------------
# Agreement with HAPI 1.3 (reference arrays made by scripts/make_hapi_references.py)


def _hapi_cases():
    ref = np.load(DATA / "hapi_reference.npz")
    meta = json.loads(str(ref["meta"]))
    return [(c, meta) for c in meta["cases"]]


@pytest.mark.parametrize("case,meta", _hapi_cases(), ids=lambda v: v.get("key", ""))
def test_matches_hapi(case, meta, hitran_dir):
    path = hitran_dir / (case["line_file"] + ".gz")
    # The reference was computed from exactly these records (the package ships them gzipped).
    records = gzip.decompress(path.read_bytes())
    assert hashlib.sha256(records).hexdigest() == meta["line_files"][case["line_file"]]
    ref = np.load(DATA / "hapi_reference.npz")[case["key"]].astype(float)
    nu = case["nu0_cm1"] + case["step_cm1"] * np.arange(case["size"])
    sigma = qogi.cross_section(
        case["species"], nu, case["temperature_K"], 101325.0, line_list=path, cutoff="hapi"
    )
    strong = ref > 0.01 * ref.max()
    max_rel = np.max(np.abs(sigma[strong] / ref[strong] - 1))
    integral = np.sum(sigma) / np.sum(ref) - 1
    assert max_rel < 5e-3, f"max relative difference {max_rel:.2e}"
    assert abs(integral) < 1e-3, f"integrated difference {integral:.2e}"


# ---------------------------------------------------------------------------
# The Voigt function


def test_faddeeva_real_part_against_scipy():
    y = np.logspace(-4, 3, 57)
    x = np.concatenate([-np.logspace(-4, 4, 161)[::-1], [0.0], np.logspace(-4, 4, 161)])
    x = np.concatenate([x, np.linspace(-25, 25, 501)])  # dense across the region limits
    X, Y = np.meshgrid(x, y)
    ref = wofz(X + 1j * Y)
    w = spectra.faddeeva(X, Y)
    rel = np.abs(w.real / ref.real - 1)
    assert rel.max() < 1e-4, (
        f"worst {rel.max():.2e} at x={X.flat[rel.argmax()]}, y={Y.flat[rel.argmax()]}"
    )
    # The imaginary part too, relative to |w|.
    assert np.max(np.abs(w.imag - ref.imag) / np.abs(ref)) < 1e-4


def test_voigt_profile_limits():
    gd, gl = 0.005, 0.05
    d = np.linspace(-1, 1, 2001)
    v = qogi.voigt_profile(d, gd, gl)
    ref = wofz((d + 1j * gl) / (gd / np.sqrt(np.log(2)))).real / (
        gd / np.sqrt(np.log(2)) * np.sqrt(np.pi)
    )
    assert np.max(np.abs(v / ref - 1)) < 1e-4
    with pytest.raises(ValueError, match="gamma_doppler_cm1"):
        qogi.voigt_profile(d, 0.0, gl)


# ---------------------------------------------------------------------------
# Partition sums, line parameters


def test_partition_sum_and_errors():
    assert qogi.partition_sum("CH4", 296.0) == pytest.approx(590.48, rel=1e-3)  # HITRAN Q(296)
    q = qogi.partition_sum("H2O", [200.0, 296.0, 800.0], isotopologue=4)
    assert q.shape == (3,) and np.all(np.diff(q) > 0)
    with pytest.raises(ValueError, match="no partition-sum"):
        qogi.partition_sum("O3", 296.0)
    with pytest.raises(ValueError, match="TIPS range"):
        qogi.partition_sum("CH4", 3000.0)
    with pytest.raises(ValueError, match="HITRAN molecule formula"):
        qogi.partition_sum("Unobtainium", 296.0)


def test_absorption_coefficient_is_sigma_times_number_density(hitran_dir):
    nu = np.linspace(3050, 3060, 1001)
    s = qogi.cross_section("CH4", nu, 300.0, 90000.0, hitran_dir / "CH4.par.gz", self_fraction=0.1)
    k = qogi.absorption_coefficient(
        "CH4", nu, 300.0, 90000.0, mole_fraction=0.1, line_list=hitran_dir / "CH4.par.gz"
    )
    n = 0.1 * 90000.0 / (1.380649e-23 * 300.0) * 1e-6
    np.testing.assert_allclose(k, s * n, rtol=1e-12)


def test_irregular_grid_and_scalar(hitran_dir):
    nu = np.linspace(3000, 3010, 1001)
    uniform = qogi.cross_section("CH4", nu, 296.0, line_list=hitran_dir / "CH4.par.gz")
    jittered = nu.copy()
    jittered[1:-1] += 1e-4 * np.sin(np.arange(nu.size - 2))
    irregular = qogi.cross_section("CH4", jittered, 296.0, line_list=hitran_dir / "CH4.par.gz")
    # Moving points by 1e-4 cm-1 changes sigma by at most the slope x 1e-4.
    slope = np.max(np.abs(np.gradient(uniform, nu)))
    assert np.max(np.abs(irregular - uniform)) <= slope * 1.1e-4
    single = qogi.cross_section("CH4", 3005.0, 296.0, line_list=hitran_dir / "CH4.par.gz")
    assert isinstance(single, float) and single == pytest.approx(uniform[500], rel=1e-12)
    with pytest.raises(ValueError, match="strictly increasing"):
        qogi.cross_section("CH4", nu[::-1], 296.0, line_list=hitran_dir / "CH4.par.gz")
    with pytest.raises(ValueError, match="cutoff"):
        qogi.cross_section("CH4", nu, 296.0, line_list=hitran_dir / "CH4.par.gz", cutoff="wide")


# ---------------------------------------------------------------------------
# Tables: interpolation error against direct computation


@pytest.mark.parametrize(
    "species,lo,hi,self_fraction",
    [
        ("CH4", 3000.0, 3100.0, 0.0),
        ("CO2", 2200.0, 2300.0, 0.0),
        ("H2O", 3700.0, 3800.0, 1.0),
    ],
)
def test_table_interpolation_error(species, lo, hi, self_fraction):
    table = qogi.cross_section_table(species, lo, hi, self_fraction=self_fraction, cache=False)
    assert table.sigma.shape == (61, table.nu_cm1.size)
    assert table.sigma.dtype == np.float32
    for t in (203.0, 296.0, 333.3, 517.0, 795.0):
        direct = qogi.cross_section(
            species, table.nu_cm1, t, cutoff=table.metadata["cutoff"], self_fraction=self_fraction
        )
        interp = table.interpolate(t)
        strong = direct > 0.01 * direct.max()
        err = np.max(np.abs(interp[strong] / direct[strong] - 1))
        assert err < 3e-3, f"{species} at {t} K: {err:.2e}"
    # d sigma / dT against a central difference of direct computations.
    t, h = 450.0, 0.5
    up = qogi.cross_section(species, table.nu_cm1, t + h, cutoff=25.0, self_fraction=self_fraction)
    dn = qogi.cross_section(species, table.nu_cm1, t - h, cutoff=25.0, self_fraction=self_fraction)
    fd = (up - dn) / (2 * h)
    der = table.derivative(t)
    strong = up > 0.01 * up.max()
    scale = np.max(np.abs(fd[strong]))
    assert np.max(np.abs(der[strong] - fd[strong])) < 0.01 * scale
    two = table.interpolate([250.0, 260.0])
    assert two.shape == (2, table.nu_cm1.size)
    np.testing.assert_allclose(two[1], table.sigma[6], rtol=1e-5)
    with pytest.raises(ValueError, match="table range"):
        table.interpolate(850.0)


# ---------------------------------------------------------------------------
# The on-disk cache


def _small_table(**kw):
    args = dict(
        species="CH4",
        nu_min_cm1=3050.0,
        nu_max_cm1=3052.0,
        temperatures_K=[250.0, 300.0, 350.0, 400.0],
    )
    args.update(kw)
    return qogi.cross_section_table(**args)


def test_table_cache_reuse_and_rebuild(tmp_path, hitran_dir):
    folder = spectra.cache_dir() / "xsec"
    t1 = _small_table()
    files = list(folder.glob("*.qxs"))
    assert len(files) == 1
    stamp = files[0].stat().st_mtime_ns
    t2 = _small_table()
    assert files[0].stat().st_mtime_ns == stamp  # loaded, not rebuilt
    assert t2.metadata == t1.metadata
    np.testing.assert_array_equal(t2.sigma, t1.sigma)
    assert t1.metadata["key"] and t1.metadata["sources"] == [str(hitran_dir / "CH4.par.gz")]

    # Every setting that changes the output makes another table.
    _small_table(pressure_Pa=50000.0)
    _small_table(self_fraction=1.0)
    _small_table(cutoff="hapi")
    _small_table(temperatures_K=[250.0, 300.0, 350.0, 410.0])
    _small_table(step_cm1=0.02)
    assert len(list(folder.glob("*.qxs"))) == 6

    # Another line-list content (one intensity changed) is another key.
    lines = qogi.load_line_list("CH4")
    arrays = {
        k: getattr(lines, k)
        for k in (
            "molecule",
            "isotopologue",
            "nu_cm1",
            "intensity",
            "gamma_air",
            "gamma_self",
            "elower_cm1",
            "n_air",
            "delta_air",
        )
    }
    arrays["intensity"] = arrays["intensity"].copy()
    arrays["intensity"][12345] *= 1.01
    changed = _small_table(line_list=qogi.LineList(**arrays))
    assert changed.metadata["key"] != t1.metadata["key"]


def test_corrupt_or_foreign_cache_file_is_rebuilt():
    t1 = _small_table()
    path = next((spectra.cache_dir() / "xsec").glob("*.qxs"))
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    t2 = _small_table()
    np.testing.assert_array_equal(t2.sigma, t1.sigma)
    assert _engine.XsecTable.load(str(path)).metadata == t2.engine.metadata  # rewritten, valid
    path.write_bytes(b"not a table")
    np.testing.assert_array_equal(_small_table().sigma, t1.sigma)
    # A valid table with another key under this name is not trusted either.
    other = _small_table(pressure_Pa=50000.0)
    shutil.copy(next(p for p in (spectra.cache_dir() / "xsec").glob("*.qxs") if p != path), path)
    again = _small_table()
    assert again.metadata["key"] == t1.metadata["key"] != other.metadata["key"]
    np.testing.assert_array_equal(again.sigma, t1.sigma)


def test_table_save_load_and_engine_handle(tmp_path):
    t = _small_table(cache=False)
    t.save(tmp_path / "t.qxs")
    back = qogi.CrossSectionTable.load(tmp_path / "t.qxs")
    np.testing.assert_array_equal(back.sigma, t.sigma)
    np.testing.assert_array_equal(back.nu_cm1, t.nu_cm1)
    assert isinstance(back.engine, _engine.XsecTable)
    assert back.engine.options.wing_cm1 == 25.0
    assert "CH4" in repr(back)
    with pytest.raises(ValueError, match="read-only"):
        t.sigma[0, 0] = 1.0  # read-only view


# ---------------------------------------------------------------------------
# Line lists and the finder


def _write_par(folder: pathlib.Path, name: str, hitran_dir, lo: float, hi: float) -> pathlib.Path:
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / name
    with open(out, "w") as dst:
        for line in read_par_lines(hitran_dir / "CH4.par.gz"):
            if lo <= float(line[3:15]) <= hi:
                dst.write(line)
    return out


def test_finder_order_and_merge(tmp_path, monkeypatch, hitran_dir):
    env = tmp_path / "env"
    a = _write_par(env, "CH4.par", hitran_dir, 3000, 3010)
    b = _write_par(env, "ch4_extra.par", hitran_dir, 3005, 3020)
    _write_par(env, "CH4X.par", hitran_dir, 3000, 3001)  # another species name: ignored
    monkeypatch.setenv("QOGI_HITRAN_PATH", str(env))
    assert spectra.find_line_lists("CH4") == [a, b]
    lines = qogi.load_line_list("CH4")
    direct = qogi.load_line_list("CH4", hitran_dir / "CH4.par.gz", nu_min_cm1=3000, nu_max_cm1=3020)
    np.testing.assert_array_equal(lines.nu_cm1, direct.nu_cm1)  # overlap counted once
    # A folder the user names comes first; a file the user names is used as is.
    user = tmp_path / "user"
    c = _write_par(user, "CH4.par", hitran_dir, 3100, 3101)
    assert spectra.find_line_lists("CH4", [user]) == [c]
    assert spectra.find_line_lists("CH4", [b]) == [b]
    # The per-user cache folder comes after $QOGI_HITRAN_PATH, before the bundled lists.
    cached = _write_par(spectra.cache_dir() / "hitran", "CH4.par", hitran_dir, 3200, 3201)
    assert spectra.find_line_lists("CH4") == [a, b]
    monkeypatch.delenv("QOGI_HITRAN_PATH")
    assert spectra.find_line_lists("CH4") == [cached]
    cached.unlink()
    assert spectra.find_line_lists("CH4") == [hitran_dir / "CH4.par.gz"]
    with pytest.raises(FileNotFoundError, match="QOGI_HITRAN_PATH"):
        spectra.find_line_lists("NO2")
    with pytest.raises(FileNotFoundError, match="not found"):
        qogi.load_line_list("CH4", tmp_path / "missing.par")


def test_default_water_list_merges_both_bundled_files(hitran_dir):
    files = spectra.find_line_lists("H2O")
    assert files == [hitran_dir / "H2O.par.gz", hitran_dir / "H2O_HITRAN2012.par.gz"]
    lines = qogi.load_line_list("H2O", nu_min_cm1=3600, nu_max_cm1=3900)
    newer = qogi.load_line_list("H2O", hitran_dir / "H2O.par.gz", nu_min_cm1=3600, nu_max_cm1=3900)
    main = lines.isotopologue == 1
    np.testing.assert_array_equal(
        lines.nu_cm1[main], newer.nu_cm1
    )  # main isotopologue: newer file only
    assert set(np.unique(lines.isotopologue)) == {1, 2, 3, 4, 5}  # + minor ones from 2012


def test_malformed_line_file_error(tmp_path, hitran_dir):
    good = [r.rstrip("\n") for r in read_par_lines(hitran_dir / "CH4.par.gz")[:3]]
    bad = good[1][:20] + "x" + good[1][21:]
    path = tmp_path / "CH4.par"
    path.write_text("\n".join([good[0], bad, good[2]]) + "\n")
    with pytest.raises(DataError, match=r"CH4\.par:2: field 'sw' \(columns 16-25\)"):
        qogi.load_line_list("CH4", path)
    path.write_text(good[0][:100] + "\n")
    with pytest.raises(DataError, match=r"CH4\.par:1: truncated record"):
        qogi.load_line_list("CH4", path)
    path.write_text("77" + good[0][2:] + "\n")
    with pytest.raises(DataError, match="unknown HITRAN molecule code 77"):
        qogi.load_line_list("CH4", path)


def test_line_list_from_arrays_and_selection():
    lines = qogi.LineList(
        molecule=[6, 6],
        isotopologue=[1, 1],
        nu_cm1=[3001.0, 3000.0],
        intensity=[1e-20, 2e-20],
        gamma_air=[0.05, 0.05],
        gamma_self=[0.07, 0.07],
        elower_cm1=[0.0, 10.0],
        n_air=[0.7, 0.7],
        delta_air=[0.0, 0.0],
    )
    np.testing.assert_array_equal(lines.nu_cm1, [3000.0, 3001.0])  # sorted
    np.testing.assert_array_equal(lines.n_self, lines.n_air)
    assert len(lines.select(min_intensity=1.5e-20)) == 1
    # One line, wide window: the integral of sigma is its intensity.
    nu = np.arange(2500.0, 3500.0, 0.005)
    s = qogi.cross_section(None, nu, 296.0, line_list=lines.select(nu_max_cm1=3000.5), cutoff=400.0)
    assert np.sum(s) * 0.005 == pytest.approx(2e-20 * 2 / np.pi * np.arctan(400 / 0.05), rel=1e-5)
    with pytest.raises(ValueError, match="gamma_air"):
        qogi.LineList(
            molecule=[6],
            isotopologue=[1],
            nu_cm1=[3000.0],
            intensity=[1e-20],
            gamma_air=[-0.05],
            gamma_self=[0.07],
            elower_cm1=[0.0],
            n_air=[0.7],
            delta_air=[0.0],
        )


# ---------------------------------------------------------------------------
# HITRANonline fetch (no network: the HTTP call is replaced)


def test_fetch_hitran_builds_the_query_and_validates(tmp_path, monkeypatch, hitran_dir):
    body = "".join(read_par_lines(hitran_dir / "CH4.par.gz")[:50]).encode()
    seen = {}

    class Reply:
        def __init__(self, data):
            self.data = data

        def read(self):
            return self.data

        def __enter__(self):
            return self

        def __exit__(self, *a):
            return False

    def fake(url, timeout):
        seen["url"] = url
        return Reply(body)

    monkeypatch.setattr(spectra, "_urlopen", fake)
    path = spectra.fetch_hitran("CH4", 2800, 3300, isotopologues=[1, 2])
    assert seen["url"] == "https://hitran.org/lbl/api?iso_ids_list=32,33&numin=2800&numax=3300"
    assert path == spectra.cache_dir() / "hitran" / "CH4_2800-3300.par"
    assert len(qogi.load_line_list("CH4")) == 50  # the cache folder is on the search path
    body = b"<html>Too many requests</html>\n"
    with pytest.raises(RuntimeError, match="truncated record"):
        spectra.fetch_hitran("CH4", 2800, 3300, folder=tmp_path / "f")
    assert not list((tmp_path / "f").glob("*.par"))

    def offline(url, timeout):
        raise OSError("Network is unreachable")

    monkeypatch.setattr(spectra, "_urlopen", offline)
    with pytest.raises(ConnectionError, match="cannot reach HITRANonline"):
        spectra.fetch_hitran("CH4", 2800, 3300)


# ---------------------------------------------------------------------------
# CLI


def test_cli_xsec_and_hitran_list(tmp_path, hitran_dir):
    out = tmp_path / "x.npz"
    env = dict(os.environ, QOGI_CACHE_DIR=str(tmp_path / "cache"))

    def qogi_cli(*args, check=True):
        return subprocess.run(
            [sys.executable, "-m", "qogi", *args],
            capture_output=True,
            text=True,
            check=check,
            env=env,
        )

    xsec = ["xsec", "CH4", "--range", "3000", "3010"]
    r = qogi_cli(*xsec, "--step", "0.01", "--temperature", "296", "--out", str(out))
    assert "25126 lines" in r.stdout
    d = np.load(out)
    assert d["nu_cm1"].size == 1001
    expect = qogi.cross_section("CH4", d["nu_cm1"], 296.0)
    np.testing.assert_allclose(d["sigma_cm2_per_molecule"], expect, rtol=1e-12)
    r = qogi_cli("hitran", "list", "CH4")
    assert "CH4.par" in r.stdout and "2832.8614-3246.3010" in r.stdout
    assert "shipped with qogi" in r.stdout and "HITRAN2020" in r.stdout
    assert "doi:10.1016/j.jqsrt.2021.107949" in r.stdout
    r = qogi_cli(*xsec, "--cutoff", "wide", check=False)
    assert r.returncode != 0 and "--cutoff" in r.stderr


# ---------------------------------------------------------------------------
# What the package ships


def test_bundled_line_lists_match_their_manifest():
    """Each shipped file holds exactly the records its provenance names: line
    count, wavenumber span and sha256 of the uncompressed records."""
    entries = spectra.bundled_line_lists()
    assert {e["species"] for e in entries} == {"CH4", "CO2", "H2O"}
    for e in entries:
        records = gzip.decompress(e["path"].read_bytes())
        assert hashlib.sha256(records).hexdigest() == e["sha256_records"], e["file"]
        lines = records.decode().splitlines()
        assert len(lines) == e["lines"]
        nu = np.array([float(r[3:15]) for r in lines])
        assert nu.min() == pytest.approx(e["nu_min_cm1"]) and nu.max() == pytest.approx(
            e["nu_max_cm1"]
        )
        assert e["citation"] and e["edition"] and e["source"]


def test_bundled_lists_cover_every_preset_channel():
    """Every channel of every shipped camera preset sees lines of the gases the
    presets quantify: CH4 over the CH4 bands, CO2 over the CO2 band."""
    cover = {}
    for e in spectra.bundled_line_lists():
        lo, hi = cover.get(e["species"], (np.inf, -np.inf))
        cover[e["species"]] = (min(lo, e["nu_min_cm1"]), max(hi, e["nu_max_cm1"]))
    for name in qogi.camera_preset_names():
        for ch in qogi.camera_preset(name).channels:
            nu, r = np.asarray(ch.nu_cm1), np.asarray(ch.response)
            band = nu[r > 0.5 * r.max()]
            lo, hi = band.min(), band.max()
            seen = [sp for sp, (a, b) in cover.items() if a < hi and b > lo]
            assert seen, f"{name} {ch.name}: no bundled lines in {lo:.0f}-{hi:.0f} cm-1"


def test_a_users_own_file_takes_precedence_over_the_bundled_one(tmp_path, monkeypatch, hitran_dir):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "CH4.par").write_text("".join(read_par_lines(hitran_dir / "CH4.par.gz")[:100]))
    monkeypatch.setenv("QOGI_HITRAN_PATH", str(mine))
    assert spectra.find_line_lists("CH4") == [mine / "CH4.par"]
    assert len(qogi.load_line_list("CH4")) == 100
    monkeypatch.delenv("QOGI_HITRAN_PATH")
    assert spectra.find_line_lists("CH4") == [hitran_dir / "CH4.par.gz"]


def test_nothing_in_the_package_reads_beside_the_checkout():
    """A user's install has nothing beside it: no source file of the package,
    the viewer or the build may refer to the project's shared folder or its
    design notes."""
    repo = pathlib.Path(__file__).resolve().parents[2]
    offenders = []
    for folder in ("python", "gui", "cpp", "cmake"):
        for f in (repo / folder).rglob("*"):
            if f.suffix in (".py", ".cc", ".h", ".cmake", ".txt", ".in") and f.is_file():
                text = f.read_text(errors="replace")
                if any(
                    w in text for w in ("../" + "shared", "shared/" + "hitran", "DESIGN" + ".md")
                ):
                    offenders.append(str(f.relative_to(repo)))
    assert not offenders, offenders
