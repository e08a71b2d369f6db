"""Make the HITRAN line-list subsets that the qogi package ships.

The package carries, gzip-compressed, every line the shipped camera presets
can see (python/qogi/data/hitran/), so that a fresh install quantifies without
downloading anything. The records are copied byte for byte from the source
files (160-character HITRAN .par records, LF endings); a subset is selected by
wavenumber only. MANIFEST.json records, per file: species, isotopologues,
wavenumber range, line count, HITRAN edition, source, citation and the sha256
of both the uncompressed records and the .gz file.

    .venv/bin/python scripts/make_bundled_hitran.py --src DIR_WITH_PAR_FILES

The source folder is the one described by its PROVENANCE.md (CH4.par, CO2.par,
H2O.par, H2O_HITRAN2012_all.par.gz). Run once; the output is committed.
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
import io
import json
import pathlib

REPO = pathlib.Path(__file__).resolve().parents[1]
OUT = REPO / "python" / "qogi" / "data" / "hitran"

HITRAN2020 = (
    'I.E. Gordon et al., "The HITRAN2020 molecular spectroscopic database", '
    "JQSRT 277 (2022) 107949, doi:10.1016/j.jqsrt.2021.107949"
)
HITRAN2012 = (
    'L.S. Rothman et al., "The HITRAN2012 molecular spectroscopic database", '
    "JQSRT 130 (2013) 4-50, doi:10.1016/j.jqsrt.2013.07.002"
)

# (output name, source file, species, nu range kept [cm-1], edition, citation, origin)
FILES = [
    (
        "CH4.par.gz",
        "CH4.par",
        "CH4",
        (0.0, 1e9),
        "HITRAN2020 (inferred from the fetch date)",
        HITRAN2020,
        "HAPI fetch of 12CH4 over 3080-3530 nm, published in the GitHub repository "
        "dermahax/spectracalc_hapi (data/CH4.data, commit "
        "8597bf110c77428e97f19ac8f6c3096347ad10cd)",
    ),
    (
        "CO2.par.gz",
        "CO2.par",
        "CO2",
        (0.0, 1e9),
        "HITRAN2012 (inferred from the fetch date)",
        HITRAN2012,
        "HAPI fetch of 12C16O2 over 2100-2300 cm-1, published in the GitHub repository "
        "dp7-PU/QCLAS (Data/CO2.data, commit e1a9b187ad13508506740e70229987a20aa9f737), "
        "CR CR LF endings normalised to LF",
    ),
    (
        "H2O.par.gz",
        "H2O.par",
        "H2O",
        (0.0, 1e9),
        "HITRAN2020 (inferred from the fetch date)",
        HITRAN2020,
        "two HAPI fetches of H2 16O placed end to end at 3333.33 cm-1: lenkaYhH/EE_data_analysis "
        "(H2O.data, commit bf4bea9e2e3c39c13248fc314e40f454d83977b0) and ErickGatica/Hapi_GUI "
        "(H2O.data, commit 9ec229b2b4de31984bbbd0387b1e93916f687d51)",
    ),
    (
        "H2O_HITRAN2012.par.gz",
        "H2O_HITRAN2012_all.par.gz",
        "H2O",
        (1800.0, 6700.0),
        "HITRAN2012 (the 01_hit12.par distribution file)",
        HITRAN2012,
        "01_hit12.par (all six H2O isotopologues) as shipped in the PyPI source distribution "
        "pyratbay 2.1.2 (tests/inputs/01_hit12.par), CRLF normalised to LF; kept: 1800-6700 cm-1, "
        "the span of every preset channel. Used after H2O.par.gz: it adds the minor "
        "isotopologues and the lines outside 2000-5000 cm-1",
    ),
]


def _records(path: pathlib.Path) -> list:
    raw = path.read_bytes()
    if path.suffix == ".gz":
        raw = gzip.decompress(raw)
    return [r for r in raw.replace(b"\r", b"").split(b"\n") if r.strip()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--src",
        type=pathlib.Path,
        required=True,
        help="folder holding CH4.par, CO2.par, H2O.par, H2O_HITRAN2012_all.par.gz",
    )
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    manifest = {
        "format": "qogi-bundled-hitran",
        "version": 1,
        "note": "HITRAN line-by-line records, byte-identical to the sources, "
        "selected by wavenumber only; data free to use with citation "
        "(hitran.org). HAPI: R.V. Kochanov et al., JQSRT 177 (2016) 15-30.",
        "files": [],
    }
    for name, src, species, (lo, hi), edition, cite, origin in FILES:
        recs = [r for r in _records(args.src / src) if lo <= float(r[3:15]) <= hi]
        body = b"\n".join(recs) + b"\n"
        buf = io.BytesIO()
        with gzip.GzipFile(filename="", mode="wb", fileobj=buf, compresslevel=9, mtime=0) as gz:
            gz.write(body)
        data = buf.getvalue()
        (OUT / name).write_bytes(data)
        nus = [float(r[3:15]) for r in recs]
        isos = sorted({int(r[2:3]) for r in recs})
        manifest["files"].append(
            {
                "file": name,
                "species": species,
                "isotopologues": isos,
                "lines": len(recs),
                "nu_min_cm1": min(nus),
                "nu_max_cm1": max(nus),
                "edition": edition,
                "citation": cite,
                "source": origin,
                "sha256_records": hashlib.sha256(body).hexdigest(),
                "sha256_gz": hashlib.sha256(data).hexdigest(),
                "bytes_gz": len(data),
            }
        )
        print(
            f"{name}: {len(recs)} lines {min(nus):.4f}-{max(nus):.4f} cm-1, "
            f"{len(data) / 1e6:.2f} MB"
        )
    (OUT / "MANIFEST.json").write_text(json.dumps(manifest, indent=2) + "\n")


if __name__ == "__main__":
    main()
