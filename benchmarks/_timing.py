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


def best_of_interleaved(fns, repeat=10, warmup=1):
    """Best wall time in seconds of each of ``fns``, run in turn ``repeat`` times (after
    ``warmup`` rounds): a ratio of two of them then compares runs made under the same
    load, where timing one after the other lets a shared machine's load drift between."""
    for _ in range(warmup):
        for fn in fns:
            fn()
    best = [float("inf")] * len(fns)
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            t = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t)
    return best


def report(name, ours, peer, target, *, higher_is_better=True, unit="x"):
    """Print one figure: the ratio and whether it meets the target."""
    ratio = ours / peer
    ok = ratio >= target if higher_is_better else ratio <= target
    sign = ">=" if higher_is_better else "<="
    print(f"   {name}: {ratio:.2f}{unit} (target {sign} {target}{unit}) {'PASS' if ok else 'MISS'}",
          flush=True)
    return ratio
