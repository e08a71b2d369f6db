"""Timing shared by the benchmark scripts (imported as a sibling module: the
scripts run with this folder first on sys.path, directly or from run_all.py)."""

from __future__ import annotations

import time


def best_time(fn, repeat: int = 3) -> float:
    """The shortest wall time of ``repeat`` calls of ``fn()`` [s]."""
    t = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        t.append(time.perf_counter() - t0)
    return min(t)
