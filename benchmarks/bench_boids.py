"""Boids step throughput (Reynolds rules, 270 deg field of view, bounded world).

* ours at 100 k boids against the 1 M boid-updates/s bound;
* ours against a scipy cKDTree implementation (query_pairs + numpy sums) at 100 k;
* ours against the naive all-pairs numpy implementation at 20 k.

Peers apply the same rules to the same neighbour sums (checked to agree to 1e-10);
only the neighbour search and the summing differ. Density: about 15 boids within the
perception radius of each.
"""

import numpy as np
from _timing import best_of, report

from simulate.boids import BoidParams, FlockState, init_flock, step
from simulate.boids import _kernels as B

DENSITY = 0.45  # boids per m^3: ~15 within the 2 m perception radius


def _setup(n, seed=0):
    side = (n / DENSITY) ** (1 / 3)
    p = BoidParams(separation_radius=0.7, alignment_radius=1.5, cohesion_radius=2.0,
                   bounds=((0, 0, 0), (side, side, side)), bounds_margin=2.0)
    rng = np.random.default_rng(seed)
    s = init_flock(n, p, rng=rng, radius=1.0)
    s.positions = rng.uniform(0, side, (n, 3))
    return p, s


def _sums_kdtree(x, v, P):
    """Neighbour sums as in :func:`simulate.boids._kernels._sums_reference`, via cKDTree pairs."""
    from scipy.spatial import cKDTree

    n = len(x)
    r2max = max(P[B._RS2], P[B._RA2], P[B._RC2])
    pairs = cKDTree(x).query_pairs(np.sqrt(r2max), output_type="ndarray")
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    d = x[j] - x[i]
    r2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    r = np.sqrt(r2)
    sp = np.linalg.norm(v, axis=1)
    h = np.divide(v, sp[:, None], out=np.zeros_like(v), where=sp[:, None] > 0)
    dot = np.sum(h[i] * d, axis=1)
    keep = (r2 < r2max) & ~((P[B._FOVCOS] > -1) & (sp[i] > 0) & (dot < P[B._FOVCOS] * r))
    i, j, d, r2 = i[keep], j[keep], d[keep], r2[keep]
    sums = np.zeros((n, 3, 3))
    counts = np.zeros((n, 3), np.int64)
    ms = (r2 < P[B._RS2]) & (r2 > 0)
    ma = r2 < P[B._RA2]
    mc = r2 < P[B._RC2]
    for k in range(3):
        sums[:, 0, k] = -np.bincount(i[ms], d[ms, k] / r2[ms], minlength=n)
        sums[:, 1, k] = np.bincount(i[ma], v[j[ma], k], minlength=n)
        sums[:, 2, k] = np.bincount(i[mc], d[mc, k], minlength=n)
    counts[:, 0] = np.bincount(i[ms], minlength=n)
    counts[:, 1] = np.bincount(i[ma], minlength=n)
    counts[:, 2] = np.bincount(i[mc], minlength=n)
    return sums, counts


def _step_kdtree(s, p, rng):
    x, v = s.positions, s.velocities
    P = B._pack(p)
    sums, counts = _sums_kdtree(x, v, P)
    steer = np.empty_like(x)
    B._finish_all(x, v, s.wander, P, False, sums, counts, steer)
    xn, vn = np.empty_like(x), np.empty_like(v)
    B._integrate(x, v, steer, np.zeros((1, 3)), P, False, xn, vn)
    s.positions, s.velocities = xn, vn
    s.time += p.dt
    return s


def _copy(s):
    return FlockState(s.positions, s.velocities, s.wander)


def main():
    from simulate.neighbours import neighbour_lists

    rng = np.random.default_rng(1)
    p, s = _setup(100_000)
    off, _ = neighbour_lists(s.positions, 2.0)
    print(f"   100 k boids, {np.diff(off).mean():.1f} neighbours within 2 m on average")
    # the cKDTree peer computes the same step
    a, b = _copy(s), _copy(s)
    step(a, p, rng=rng)
    _step_kdtree(b, p, rng)
    err = np.abs(a.velocities - b.velocities).max()
    print(f"   grid vs cKDTree step: max |dv| = {err:.2e}")
    ours = best_of(lambda: step(s, p, rng=rng), repeat=5)
    peer = best_of(lambda: _step_kdtree(b, p, rng), repeat=3)
    rate = 100_000 / ours
    print(f"   ours: {ours * 1e3:.1f} ms/step = {rate / 1e6:.2f} M boid-updates/s; "
          f"cKDTree: {peer * 1e3:.1f} ms/step")
    report("boid updates/s at 100 k vs 1 M/s", rate, 1e6, 1.0)
    report("step at 100 k vs cKDTree", 1 / ours, 1 / peer, 4.0)

    p, s = _setup(20_000, seed=2)
    a = _copy(s)
    ours = best_of(lambda: step(s, p, rng=rng), repeat=5)
    naive = best_of(lambda: step(a, p, rng=rng, method="reference"), repeat=1, warmup=0)
    print(f"   20 k boids: ours {ours * 1e3:.2f} ms/step; naive all-pairs numpy "
          f"{naive * 1e3:.0f} ms/step")
    report("step at 20 k vs naive all-pairs numpy", 1 / ours, 1 / naive, 100.0)


if __name__ == "__main__":
    main()
