"""Timing helper shared by the benchmarks: best of N wall-clock runs."""

import time


def best_of(fn, repeat=3, warmup=1):
    """Best wall time in seconds of ``fn()`` over ``repeat`` runs after ``warmup`` runs."""
    for _ in range(warmup):
        fn()
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def report(name, ours, peer, target, *, higher_is_better=True, unit="x"):
    """Print one figure: the ratio and whether it meets the target."""
    ratio = ours / peer
    ok = ratio >= target if higher_is_better else ratio <= target
    sign = ">=" if higher_is_better else "<="
    print(f"   {name}: {ratio:.2f}{unit} (target {sign} {target}{unit}) {'PASS' if ok else 'MISS'}",
          flush=True)
    return ratio
