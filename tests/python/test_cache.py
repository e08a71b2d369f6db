"""qogi.cache: one per-user cache folder, file names carrying the writer's
format version (a file of another version is never read, and is rebuilt),
atomic writes that never stop the computation."""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi import cache
from qogi.physics import spectra


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Every test gets its own cache folder and no inherited search path."""
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("QOGI_HITRAN_PATH", raising=False)


def test_the_cache_folder_honours_qogi_cache_dir_then_xdg_cache_home(monkeypatch, tmp_path):
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path / "mine"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "mine"
    assert spectra.cache_dir() == tmp_path / "mine"  # the same function
    monkeypatch.delenv("QOGI_CACHE_DIR")
    assert cache.cache_dir() == tmp_path / "xdg" / "qogi"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.cache_dir() == tmp_path / "home" / ".cache" / "qogi"


def test_a_cache_name_carries_its_format_version(monkeypatch, tmp_path):
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path))
    assert (
        cache.cache_path("xsec", "CH4_1-2_ab", "3-1", ".qxs")
        == tmp_path / "xsec" / "CH4_1-2_ab.v3-1.qxs"
    )
    assert cache.cache_path("xsec", "a", 2, ".qxs") != cache.cache_path("xsec", "a", 3, ".qxs")
    with pytest.raises(ValueError, match="stem"):
        cache.cache_path("xsec", "../escape", 1, ".qxs")


def test_store_is_atomic_and_a_cache_that_cannot_be_written_is_skipped(tmp_path):
    target = tmp_path / "k" / "f.v1.bin"
    assert cache.store(target, lambda tmp: tmp.write_bytes(b"abc"))
    assert target.read_bytes() == b"abc"

    def boom(tmp):
        tmp.write_bytes(b"half")
        raise RuntimeError("writer failed")

    with pytest.raises(RuntimeError):
        cache.store(target, boom)
    assert target.read_bytes() == b"abc"
    assert sorted(p.name for p in target.parent.iterdir()) == ["f.v1.bin"]  # no temporary left
    (tmp_path / "ro").write_text("a file where the folder should be")
    assert cache.store(tmp_path / "ro" / "x.v1.bin", lambda tmp: tmp.write_bytes(b"x")) is False


def _small_table():
    return qogi.cross_section_table("CH4", 3050.0, 3052.0, temperatures_K=[250.0, 300.0, 350.0])


def test_a_cross_section_table_of_another_format_version_is_ignored_and_rebuilt(monkeypatch):
    """A table cached under the current version is reused; after a format
    bump the old file is not read (it stays untouched) and a table is built
    and stored under the new version's name. A file under the current name
    written by an older format (here: garbage with the right name) is
    rebuilt, not misread."""
    t1 = _small_table()
    folder = spectra.cache_dir() / "xsec"
    (old,) = folder.glob("*.qxs")
    assert old.name.endswith(f".v{spectra._xsec_cache_version()}.qxs")
    stamp = old.stat().st_mtime_ns
    monkeypatch.setattr(spectra, "_xsec_cache_version", lambda: "99-1")
    t2 = _small_table()
    (new,) = folder.glob("*.v99-1.qxs")
    assert old.stat().st_mtime_ns == stamp and new != old
    np.testing.assert_array_equal(t2.sigma, t1.sigma)
    new.write_bytes(b"QXS of a format this qogi does not know")
    np.testing.assert_array_equal(_small_table().sigma, t1.sigma)
    assert new.stat().st_size > 1000  # rebuilt and stored again


def test_the_demo_recording_is_named_by_its_format_version(monkeypatch, tmp_path):
    pytest.importorskip("dearpygui")
    from qogi.contract import VERSION
    from qogi_gui import demo

    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path))
    p = demo.demo_path()
    assert p.parent == tmp_path / "demo" and p.name.endswith(f".v{VERSION}.h5")
    assert demo.demo_path(tmp_path / "else") == tmp_path / "else" / p.name
