"""Files qogi writes besides recordings and results go through qogi.files:
complete or absent, never a stray temporary."""

from __future__ import annotations

import numpy as np

import qogi
from qogi.physics import spectra


def test_the_cross_section_cache_is_written_whole_and_reused(tmp_path, monkeypatch):
    monkeypatch.setenv("QOGI_CACHE_DIR", str(tmp_path))
    kw = dict(step_cm1=0.05, temperatures_K=[280.0, 300.0], cache=True)
    t = spectra.cross_section_table("CH4", 2990, 3000, **kw)
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert len(files) == 1 and files[0].suffix == ".qxs"
    assert not files[0].name.startswith(".qogi-tmp")
    again = spectra.cross_section_table("CH4", 2990, 3000, **kw)  # read back from the cache
    np.testing.assert_array_equal(again.derivative(290.0), t.derivative(290.0))


def test_a_spectral_response_csv_replaces_the_old_file_only_when_complete(tmp_path, monkeypatch):
    p = tmp_path / "band.csv"
    p.write_text("old\n")
    ch = qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um")

    def broken_writer(fh):
        class W:
            def writerow(self, row):
                if row[0] != "wavenumber_cm1":
                    raise OSError(28, "No space left on device")

        return W()

    import csv

    monkeypatch.setattr(csv, "writer", broken_writer)
    try:
        ch.to_csv(p)
    except OSError:
        pass
    assert p.read_text() == "old\n" and [q.name for q in tmp_path.iterdir()] == ["band.csv"]
    monkeypatch.undo()
    ch.to_csv(p)
    assert p.read_text().startswith("wavenumber_cm1,response")
