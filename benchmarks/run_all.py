"""Run every benchmark (``benchmarks/bench_*.py``); each prints its figures as ratios
against a peer or a bound measured in the same run.

Usage: ``python benchmarks/run_all.py [NAME ...]`` (names without ``bench_``).

Each benchmark runs in a process of its own, so no thread pool, JIT cache or import
state left by one (OpenMP threads spinning after a TSDF step, say) skews the next.
"""

import os
import subprocess
import sys
import time
from pathlib import Path


def main(argv):
    here = Path(__file__).parent
    files = sorted(here.glob("bench_*.py"))
    if argv:
        files = [f for f in files if f.stem.removeprefix("bench_") in argv]
    env = dict(os.environ)
    env.setdefault("NUMBA_THREADING_LAYER", "omp")
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(here.parent), env.get("PYTHONPATH"))
                                        if p)
    failed = 0
    for f in files:
        print(f"== {f.stem}", flush=True)
        t = time.perf_counter()
        rc = subprocess.call([sys.executable, str(f)], env=env, cwd=here.parent)
        if rc:  # keep going: one broken benchmark must not hide the rest
            failed += 1
            print(f"   FAILED: exit status {rc}")
        print(f"   ({time.perf_counter() - t:.1f} s)", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
