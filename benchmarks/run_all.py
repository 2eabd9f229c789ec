"""Run every benchmark (``benchmarks/bench_*.py``); each prints its figures as ratios
against a peer or a bound measured in the same run.

Usage: ``python benchmarks/run_all.py [NAME ...]`` (names without ``bench_``).
"""

import importlib.util
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
import cv2  # noqa: E402,F401


def main(argv):
    here = Path(__file__).parent
    sys.path.insert(0, str(here.parent))
    files = sorted(here.glob("bench_*.py"))
    if argv:
        files = [f for f in files if f.stem.removeprefix("bench_") in argv]
    failed = 0
    for f in files:
        print(f"== {f.stem}", flush=True)
        spec = importlib.util.spec_from_file_location(f.stem, f)
        mod = importlib.util.module_from_spec(spec)
        t = time.perf_counter()
        try:
            spec.loader.exec_module(mod)
            mod.main()
        except Exception as exc:  # keep going: one broken benchmark must not hide the rest
            failed += 1
            print(f"   FAILED: {type(exc).__name__}: {exc}")
        print(f"   ({time.perf_counter() - t:.1f} s)", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
