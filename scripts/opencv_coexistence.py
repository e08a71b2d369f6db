"""qogi's engine and opencv-python-headless's cv2 in one process.

The qogi extension links OpenCV (Debian's libopencv_* in a source build; in a
wheel, copies that auditwheel renames with a hash, e.g.
``libopencv_core-1a2b3c4d.so.406``); ``cv2`` from opencv-python-headless carries
its own OpenCV build. Python loads extension modules with RTLD_LOCAL, so
neither module's symbols are in the global scope where the other could bind
to them, and the renamed sonames cannot be confused by the loader. This script
shows it: it imports both in the order given (``qogi-first`` or
``cv2-first``), runs dense optical flow through each on a textured frame
moved by a known sub-pixel shift, and checks that both recover the shift.

    python scripts/opencv_coexistence.py [qogi-first|cv2-first]
"""

from __future__ import annotations

import sys

import numpy as np


def main(order: str) -> None:
    if order == "cv2-first":
        import cv2

        import qogi
    else:
        import cv2

        import qogi
    rng = np.random.default_rng(7)
    h, w = 96, 128
    noise = rng.standard_normal((h + 8, w + 8)).astype(np.float32)
    tex = cv2.GaussianBlur(noise, (0, 0), 2.0)
    shift = (1.25, -0.75)  # (dx, dy) px
    m = np.float32([[1, 0, shift[0]], [0, 1, shift[1]]])
    prev = tex[4 : 4 + h, 4 : 4 + w].copy()
    moved = cv2.warpAffine(tex, m, (w + 8, h + 8), flags=cv2.INTER_CUBIC)[4 : 4 + h, 4 : 4 + w]
    inner = (slice(16, -16), slice(16, -16))

    u8 = lambda a: np.clip((a - tex.min()) / (tex.max() - tex.min()) * 255, 0, 255).astype(np.uint8)
    cv_flow = cv2.calcOpticalFlowFarneback(u8(prev), u8(moved), None, 0.5, 3, 15, 5, 7, 1.5, 0)
    cv_shift = (float(np.median(cv_flow[..., 0][inner])), float(np.median(cv_flow[..., 1][inner])))

    f = qogi.optical_flow(prev - prev.min() + 1.0, moved - prev.min() + 1.0, method="horn_schunck")
    q_shift = (float(np.median(np.asarray(f.u)[inner])), float(np.median(np.asarray(f.v)[inner])))

    print(
        f"opencv_coexistence ({order}): cv2 {cv2.__version__} Farneback "
        f"({cv_shift[0]:.3f}, {cv_shift[1]:.3f}) px, qogi horn_schunck "
        f"({q_shift[0]:.3f}, {q_shift[1]:.3f}) px, truth {shift}"
    )
    for name, got in (("cv2", cv_shift), ("qogi", q_shift)):
        err = np.hypot(got[0] - shift[0], got[1] - shift[1])
        if not err < 0.15:
            raise SystemExit(f"{name} flow is off by {err:.3f} px in one process with the other")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "qogi-first")
