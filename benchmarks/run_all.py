"""Runs every benchmark script in this folder (bench_*.py) in turn."""

import pathlib
import runpy
import sys

here = pathlib.Path(__file__).parent
scripts = sorted(here.glob("bench_*.py"))
only = set(sys.argv[1:])
for script in scripts:
    if only and script.stem not in only and script.stem.removeprefix("bench_") not in only:
        continue
    print(f"\n=== {script.name} ===", flush=True)
    runpy.run_path(str(script), run_name="__main__")
