"""Every method on rotation and shear: the scenes of
tests/python/test_velocimetry_rigid.py (issue 20), as a table.

Rigid motion (rotation + translation, 1-3 px/frame) of a real infrared frame
(the FLIR sample in $QOGI_SHARED_DIR/samples/flir, as a column-like field) and
of a synthetic column texture, and a steady rotating vortex pair in a column
field (cold pair, and the last pair of a 4-frame warm-started sequence). Mean
end-point error [px] over the interior (16 px margin). `fluid (before)` is
the fluid method with the settings it had before the patch-search start.

Usage: QOGI_SHARED_DIR=/path/to/shared python scripts/velocimetry_rigid.py
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

import qogi
from qogi.measure import velocimetry as vel

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "python"))
import test_velocimetry_rigid as scenes  # noqa: E402

BEFORE = dict(patch_search_scale=-1, warm_levels=3, warps=2, iterations=20)


def main():
    shared = Path(os.environ.get("QOGI_SHARED_DIR", REPO.parent / "shared"))
    columns = {"synthetic": scenes.synthetic_column()}
    if (shared / "samples" / "flir" / "SampleSEQ.seq").is_file():
        columns = {"FLIR": scenes.ir_column.__wrapped__(shared), **columns}
    else:
        print(f"FLIR sample not in {shared}: the synthetic column only")
    frames, tu_v, tv_v = scenes.vortex_pair.__wrapped__()
    runs = [
        ("fluid", None, "fluid (default)"),
        ("fluid", vel.options_for("fluid", **BEFORE), "fluid (before)"),
    ]
    runs += [(m, None, m) for m in vel.METHODS if m != "fluid"]
    cols = [
        f"{name} {th:+.3f} rad ({dx:+.1f}, {dy:+.1f}) px"
        for name in columns
        for th, dx, dy in scenes.MOTIONS
    ]
    cols += ["vortex pair", "vortex pair, sequence"]
    print("| method | " + " | ".join(cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    for method, options, label in runs:
        row = []
        for col in columns.values():
            for th, dx, dy in scenes.MOTIONS:
                nxt, tu, tv = scenes.rigid(col, th, dx, dy)
                f = qogi.optical_flow(col, nxt, method=method, options=options)
                row.append(np.hypot(f.u - tu, f.v - tv)[16:-16, 16:-16].mean())
        f = qogi.optical_flow(frames[0], frames[1], method=method, options=options)
        row.append(np.hypot(f.u - tu_v, f.v - tv_v)[16:-16, 16:-16].mean())
        s = qogi.optical_flow_sequence(frames, method=method, options=options)
        row.append(np.hypot(s.u[-1] - tu_v, s.v[-1] - tv_v)[16:-16, 16:-16].mean())
        print(f"| {label} | " + " | ".join(f"{e:.3f}" for e in row) + " |")


if __name__ == "__main__":
    main()
