"""Compiled kernels of PatchMatch multi-view stereo (numba, parallel over image rows).

One call of :func:`sweep` updates the pixels of one colour of the red-black
checkerboard of a reference view: each pixel tries the planes of its neighbours of the
other colour (which this sweep does not write, so rows run in parallel without races),
then random perturbations of its own plane, and keeps the cheapest. The caller
(:mod:`reconstruct.mvs.patchmatch`) alternates colours and iterations.

Planes are per pixel: a depth ``D`` (z in the reference camera) and a unit normal ``N``
(reference camera frame, facing the camera). The photometric cost of a plane against
one source view is ``1 - NCC`` of a bilateral-weighted window sampled every ``step``
pixels, the source sampled through the plane's homography; it is 2 where the window
has no texture or leaves the source image. The multi-view cost is the mean of the
``top_k`` cheapest source views (of a pixel's active sources, see :func:`sweep`). With
source depth maps (``geom`` > 0), each view's cost adds ``geom * min(e, max_reproj)``,
``e`` the forward-backward reprojection error (px) through that view's depth map
(geometric consistency, as in ACMM).

Random numbers come from a counter-based hash of (seed, pixel, iteration, draw), so the
result does not depend on the number of threads: the same seed gives the same bytes.
"""

from __future__ import annotations

import numba as nb
import numpy as np

__all__ = ["bilateral_weights", "sweep", "initialise", "final_costs"]

_BAD = 2.0


@nb.njit(cache=True, inline="always")
def _uniform(seed, a, b, c):
    """Uniform in [0, 1) from four integers (splitmix64 finaliser)."""
    z = np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
    z ^= np.uint64(a) * np.uint64(0xBF58476D1CE4E5B9)
    z ^= np.uint64(b) * np.uint64(0x94D049BB133111EB)
    z ^= np.uint64(c) * np.uint64(0xD6E8FEB86659FD93)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@nb.njit(cache=True)
def _row(k, h):
    """The k-th row a parallel loop visits: rows 0, 16, 32, ..., then 1, 17, ..., so that
    each thread's contiguous share of the loop spans the whole image (the work per row
    is uneven: textureless rows are cheap) and both cores stay busy. Rows are
    independent within a call, so the order changes no result."""
    q = h // 16
    big = (h % 16) * (q + 1)  # the first h % 16 residues have q + 1 rows, the others q
    if k < big:
        return k // (q + 1) + 16 * (k % (q + 1))
    return h % 16 + (k - big) // q + 16 * ((k - big) % q)


@nb.njit(parallel=True, cache=True, fastmath=True)
def bilateral_weights(ref, radius, step, sigma_color, sigma_space):
    """Per-pixel window weights (H, W, n) and the weighted sums of the reference
    window: (H, W, 3) = (sum w, sum w a, sum w a^2)."""
    h, w = ref.shape
    m = 2 * (radius // step) + 1
    n = m * m
    wts = np.zeros((h, w, n), np.float32)
    stats = np.zeros((h, w, 3), np.float32)
    for y in nb.prange(h):
        for x in range(w):
            c = ref[y, x]
            k = 0
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            for j in range(-radius, radius + 1, step):
                for i in range(-radius, radius + 1, step):
                    yy = min(max(y + j, 0), h - 1)
                    xx = min(max(x + i, 0), w - 1)
                    a = ref[yy, xx]
                    dc = a - c
                    wt = np.exp(-dc * dc / (2.0 * sigma_color * sigma_color)
                                - (i * i + j * j) / (2.0 * sigma_space * sigma_space))
                    wts[y, x, k] = wt
                    s0 += wt
                    s1 += wt * a
                    s2 += wt * a * a
                    k += 1
            stats[y, x, 0] = s0
            stats[y, x, 1] = s1
            stats[y, x, 2] = s2
    return wts, stats


@nb.njit(cache=True, inline="always")
def _window(x, y, ref, wts, radius, step, win, xs, ys):
    """The reference window of (x, y), once per pixel for all the planes it tries: its
    sample columns ``xs`` and rows ``ys`` (clamped at the border), and per sample (row by
    row) its weight ``win[k]`` and weighted grey level ``win[n + k]``."""
    h, w = ref.shape
    m = 2 * (radius // step) + 1
    n = m * m
    for i in range(m):
        xs[i] = min(max(x - radius + i * step, 0), w - 1)
        ys[i] = min(max(y - radius + i * step, 0), h - 1)
    k = 0
    for j in range(m):
        for i in range(m):
            wt = wts[y, x, k]
            win[k] = wt
            win[n + k] = wt * ref[ys[j], xs[i]]
            k += 1


@nb.njit(cache=True, inline="always")
def _row_buffers(ns, radius, step):
    """A thread's buffers for one row: the per-source costs (twice: a copy to sort) and
    the reference window of :func:`_window` (weights and weighted grey levels, sample
    columns and rows)."""
    m = 2 * (radius // step) + 1
    return (np.empty(2 * max(ns, 1)), np.empty(2 * m * m), np.empty(m, np.int64),
            np.empty(m, np.int64))


@nb.njit(cache=True, fastmath=True)
def _view_cost(x, y, d, n0, n1, n2, s, stats, src, sizes, kinv, hm, min_var, win, xs, ys):
    """1 - bilateral NCC of the plane (d, n) at (x, y) against source view s; the
    reference window from :func:`_window`.

    ``hm[s]`` = (K_s R K_r^-1 row by row, K_s t): the plane's homography
    K_s (R + t n^T / dp) K_r^-1 is then K_s R K_r^-1 + (K_s t) (n^T K_r^-1) / dp.
    The window is a rectangle of the reference and the homography is projective, so
    when its four corners land inside the source in front of it, every sample does:
    the samples are then read without a test each."""
    s0 = stats[y, x, 0]
    ma = stats[y, x, 1] / s0
    va = stats[y, x, 2] / s0 - ma * ma
    if va < min_var:  # a textureless window matches nothing: no need to warp it
        return _BAD
    # the point and the plane offset: n . X = dp for X on the plane
    rx = kinv[0, 0] * x + kinv[0, 1] * y + kinv[0, 2]
    ry = kinv[1, 0] * x + kinv[1, 1] * y + kinv[1, 2]
    rz = kinv[2, 0] * x + kinv[2, 1] * y + kinv[2, 2]
    dp = d * (n0 * rx + n1 * ry + n2 * rz)
    if abs(dp) < 1e-12:
        return _BAD
    g0 = (n0 * kinv[0, 0] + n1 * kinv[1, 0] + n2 * kinv[2, 0]) / dp
    g1 = (n0 * kinv[0, 1] + n1 * kinv[1, 1] + n2 * kinv[2, 1]) / dp
    g2 = (n0 * kinv[0, 2] + n1 * kinv[1, 2] + n2 * kinv[2, 2]) / dp
    e0 = hm[s, 9]
    e1 = hm[s, 10]
    e2 = hm[s, 11]
    h00 = hm[s, 0] + e0 * g0
    h01 = hm[s, 1] + e0 * g1
    h02 = hm[s, 2] + e0 * g2
    h10 = hm[s, 3] + e1 * g0
    h11 = hm[s, 4] + e1 * g1
    h12 = hm[s, 5] + e1 * g2
    h20 = hm[s, 6] + e2 * g0
    h21 = hm[s, 7] + e2 * g1
    h22 = hm[s, 8] + e2 * g2
    umax = sizes[s, 0] - 1.001
    vmax = sizes[s, 1] - 1.001
    m = xs.shape[0]
    for c in range(4):
        cx = xs[0] if c < 2 else xs[m - 1]
        cy = ys[0] if c % 2 == 0 else ys[m - 1]
        zz = h20 * cx + h21 * cy + h22
        if zz <= 1e-12:
            return _BAD
        u = (h00 * cx + h01 * cy + h02) / zz
        v = (h10 * cx + h11 * cy + h12) / zz
        if u < 0.0 or v < 0.0 or u > umax or v > vmax:
            return _BAD
    img = src[s]
    n = m * m
    sb = 0.0
    sbb = 0.0
    sab = 0.0
    k = 0
    for j in range(m):
        yy = ys[j]
        pu = h01 * yy + h02
        pv = h11 * yy + h12
        pz = h21 * yy + h22
        for i in range(m):
            xx = xs[i]
            iz = 1.0 / (h20 * xx + pz)
            u = (h00 * xx + pu) * iz
            v = (h10 * xx + pv) * iz
            x0 = int(u)
            y0 = int(v)
            fx = u - x0
            fy = v - y0
            p00 = img[y0, x0]
            p01 = img[y0, x0 + 1]
            p10 = img[y0 + 1, x0]
            p11 = img[y0 + 1, x0 + 1]
            a = p00 + fx * (p01 - p00)
            b = a + fy * (p10 + fx * (p11 - p10) - a)
            wt = win[k]
            wb = wt * b
            sb += wb
            sbb += wb * b
            sab += win[n + k] * b
            k += 1
    mb = sb / s0
    vb = sbb / s0 - mb * mb
    if vb < min_var:
        return _BAD
    ncc = (sab / s0 - ma * mb) / np.sqrt(va * vb)
    return 1.0 - max(-1.0, min(1.0, ncc))


@nb.njit(cache=True, fastmath=True)
def _reproj_error(x, y, d, s, kinv, kr, ks, rs, ts, sdepth, sizes, max_err):
    """Forward-backward reprojection error (px) of (x, y) at depth d through view s."""
    X0 = d * (kinv[0, 0] * x + kinv[0, 1] * y + kinv[0, 2])
    X1 = d * (kinv[1, 0] * x + kinv[1, 1] * y + kinv[1, 2])
    X2 = d * (kinv[2, 0] * x + kinv[2, 1] * y + kinv[2, 2])
    R = rs[s]
    t = ts[s]
    K = ks[s]
    Y0 = R[0, 0] * X0 + R[0, 1] * X1 + R[0, 2] * X2 + t[0]
    Y1 = R[1, 0] * X0 + R[1, 1] * X1 + R[1, 2] * X2 + t[1]
    Y2 = R[2, 0] * X0 + R[2, 1] * X1 + R[2, 2] * X2 + t[2]
    if Y2 <= 1e-12:
        return max_err
    u = (K[0, 0] * Y0 + K[0, 1] * Y1) / Y2 + K[0, 2]
    v = K[1, 1] * Y1 / Y2 + K[1, 2]
    ui = int(u + 0.5)
    vi = int(v + 0.5)
    if ui < 0 or vi < 0 or ui >= sizes[s, 0] or vi >= sizes[s, 1]:
        return max_err
    ds = sdepth[s, vi, ui]
    if ds <= 0.0:
        return max_err
    # back from the source pixel at its depth, into the reference
    zx = (ui - K[0, 2] - K[0, 1] * (vi - K[1, 2]) / K[1, 1]) / K[0, 0]
    zy = (vi - K[1, 2]) / K[1, 1]
    W0 = ds * zx - t[0]
    W1 = ds * zy - t[1]
    W2 = ds - t[2]
    Z0 = R[0, 0] * W0 + R[1, 0] * W1 + R[2, 0] * W2
    Z1 = R[0, 1] * W0 + R[1, 1] * W1 + R[2, 1] * W2
    Z2 = R[0, 2] * W0 + R[1, 2] * W1 + R[2, 2] * W2
    if Z2 <= 1e-12:
        return max_err
    px = (kr[0, 0] * Z0 + kr[0, 1] * Z1) / Z2 + kr[0, 2]
    py = kr[1, 1] * Z1 / Z2 + kr[1, 2]
    e = np.sqrt((px - x) ** 2 + (py - y) ** 2)
    return min(e, max_err)


@nb.njit(cache=True, fastmath=True)
def _cost(x, y, d, n0, n1, n2, scratch, win, xs, ys, stats, src, sizes, kinv, kr, ks, rs, ts,
          hm, min_var, top_k, geom, sdepth, max_reproj, mask):
    """Multi-view cost: the mean of the top_k cheapest source views among those whose bit
    is set in ``mask`` (the others count as unmatched, cost 2). ``scratch[:ns]`` keeps
    each source's cost, in source order."""
    ns = ks.shape[0]
    for s in range(ns):
        if not (mask >> s) & 1:
            scratch[s] = _BAD + geom * max_reproj
            continue
        c = _view_cost(x, y, d, n0, n1, n2, s, stats, src, sizes, kinv, hm, min_var, win, xs,
                       ys)
        if geom > 0.0:
            c += geom * _reproj_error(x, y, d, s, kinv, kr, ks, rs, ts, sdepth, sizes,
                                      max_reproj)
        scratch[s] = c
    k = min(top_k, ns)
    if k == 1:
        best = scratch[0]
        for s in range(1, ns):
            best = min(best, scratch[s])
        return best
    for s in range(ns):
        scratch[ns + s] = scratch[s]
    total = 0.0
    for j in range(k):  # partial selection sort of the copy: the k smallest
        best = ns + j
        for i in range(ns + j + 1, 2 * ns):
            if scratch[i] < scratch[best]:
                best = i
        tmp = scratch[ns + j]
        scratch[ns + j] = scratch[best]
        scratch[best] = tmp
        total += scratch[ns + j]
    return total / k


@nb.njit(cache=True, inline="always")
def _best_sources(scratch, ns, nact):
    """The bits of the ``nact`` cheapest sources in ``scratch[:ns]`` (all when nact = 0 or
    nact >= ns)."""
    if nact <= 0 or nact >= ns:
        return (1 << ns) - 1
    mask = 0
    for _ in range(nact):
        b = -1
        for s in range(ns):
            if not (mask >> s) & 1 and (b < 0 or scratch[s] < scratch[b]):
                b = s
        mask |= 1 << b
    return mask


@nb.njit(cache=True, inline="always")
def _keep_better(c, d, m0, m1, m2, best):
    """Keep (d, m) in ``best`` = (cost, depth, normal) when its cost ``c`` is lower; True
    when it did."""
    if c < best[0]:
        best[0] = c
        best[1] = d
        best[2] = m0
        best[3] = m1
        best[4] = m2
        return True
    return False


@nb.njit(cache=True, fastmath=True, inline="always")
def _random_normal(seed, x, y, it, draw, kinv, out):
    """A random unit normal facing the camera (towards -ray) at (x, y)."""
    u1 = _uniform(seed, x * 65536 + y, it, draw)
    u2 = _uniform(seed, x * 65536 + y, it, draw + 1)
    z = 2.0 * u1 - 1.0
    r = np.sqrt(max(0.0, 1.0 - z * z))
    a = 2.0 * np.pi * u2
    n0 = r * np.cos(a)
    n1 = r * np.sin(a)
    n2 = z
    rx = kinv[0, 0] * x + kinv[0, 1] * y + kinv[0, 2]
    ry = kinv[1, 0] * x + kinv[1, 1] * y + kinv[1, 2]
    rz = kinv[2, 0] * x + kinv[2, 1] * y + kinv[2, 2]
    if n0 * rx + n1 * ry + n2 * rz > 0:
        n0, n1, n2 = -n0, -n1, -n2
    out[0] = n0
    out[1] = n1
    out[2] = n2


@nb.njit(cache=True, inline="always")
def _load(best, C, D, N, y, x):
    """``best`` = (cost, depth, normal) of pixel (x, y)."""
    best[0] = C[y, x]
    best[1] = D[y, x]
    best[2] = N[y, x, 0]
    best[3] = N[y, x, 1]
    best[4] = N[y, x, 2]


@nb.njit(cache=True, inline="always")
def _store(best, C, D, N, y, x):
    """Pixel (x, y) takes the plane and cost in ``best``."""
    C[y, x] = best[0]
    D[y, x] = best[1]
    N[y, x, 0] = best[2]
    N[y, x, 1] = best[3]
    N[y, x, 2] = best[4]


@nb.njit(cache=True, fastmath=True, inline="always")
def _carried(D, N, qx, qy, kinv, rx, ry, rz):
    """The depth at which the plane of pixel (qx, qy) meets the ray (rx, ry, rz) of
    another pixel; the neighbour's own depth when the ray nearly parallels the plane or
    the carried depth is not within 10 % of it."""
    m0 = N[qy, qx, 0]
    m1 = N[qy, qx, 1]
    m2 = N[qy, qx, 2]
    qrx = kinv[0, 0] * qx + kinv[0, 1] * qy + kinv[0, 2]
    qry = kinv[1, 0] * qx + kinv[1, 1] * qy + kinv[1, 2]
    qrz = kinv[2, 0] * qx + kinv[2, 1] * qy + kinv[2, 2]
    d = D[qy, qx]
    den = m0 * rx + m1 * ry + m2 * rz
    if abs(den) > 1e-9:
        dd = d * (m0 * qrx + m1 * qry + m2 * qrz) / den
        if dd > 0 and abs(dd - d) < 0.1 * d:
            return dd
    return d


@nb.njit(cache=True, fastmath=True, inline="always")
def _perturbed(best, perturb, depth_too, seed, pix, x, y, it, base, kinv, nrm):
    """The plane in ``best`` perturbed for refinement: its normal by ``2 perturb`` times
    a random unit vector (draw ``base + 1``), renormalised, and with ``depth_too`` its
    inverse depth by up to ``perturb`` relative (draw ``base``)."""
    d = best[1]
    if depth_too:
        u = _uniform(seed, pix, it, base)
        d = 1.0 / (1.0 / d * (1.0 + perturb * (2.0 * u - 1.0)))
    _random_normal(seed, x, y, it, base + 1, kinv, nrm)
    m0 = best[2] + perturb * 2.0 * nrm[0]
    m1 = best[3] + perturb * 2.0 * nrm[1]
    m2 = best[4] + perturb * 2.0 * nrm[2]
    ln = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
    return d, m0 / ln, m1 / ln, m2 / ln


@nb.njit(parallel=True, cache=True, fastmath=True)
def initialise(D, N, dmin, dmax, kinv, seed):
    """Random planes: depth uniform in inverse depth over [dmin, dmax], normal random
    facing the camera."""
    h, w = D.shape
    for y in nb.prange(h):
        nrm = np.empty(3)
        for x in range(w):
            u = _uniform(seed, x * 65536 + y, 0, 0)
            D[y, x] = 1.0 / (1.0 / dmax + u * (1.0 / dmin - 1.0 / dmax))
            _random_normal(seed, x, y, 0, 1, kinv, nrm)
            N[y, x, 0] = nrm[0]
            N[y, x, 1] = nrm[1]
            N[y, x, 2] = nrm[2]


@nb.njit(parallel=True, cache=True, fastmath=True)
def final_costs(D, N, C, S, nact, ref, wts, stats, src, sizes, kinv, kr, ks, rs, ts, hm,
                radius, step, min_var, top_k, geom, sdepth, max_reproj):
    """The cost of every pixel's current plane against every source (after
    initialisation, or to re-score), and in ``S`` the bits of its ``nact`` best sources."""
    h, w = D.shape
    ns = ks.shape[0]
    every = (1 << ns) - 1
    for k in nb.prange(h):
        y = _row(k, h)
        scratch, win, xs, ys = _row_buffers(ns, radius, step)
        for x in range(w):
            _window(x, y, ref, wts, radius, step, win, xs, ys)
            C[y, x] = _cost(x, y, D[y, x], N[y, x, 0], N[y, x, 1], N[y, x, 2], scratch, win,
                            xs, ys, stats, src, sizes, kinv, kr, ks, rs, ts, hm, min_var,
                            top_k, geom, sdepth, max_reproj, every)
            S[y, x] = _best_sources(scratch, ns, nact)


@nb.njit(parallel=True, cache=True, fastmath=True)
def sweep(colour, it, seed, D, N, C, S, nact, full, dmin, dmax, ref, wts, stats, src, sizes,
          kinv, kr, ks, rs, ts, hm, radius, step, min_var, top_k, geom, sdepth, max_reproj,
          perturb, random_plane):
    """One red-black half-sweep: propagation from the four directions, then refinement
    (a perturbed depth and normal, a perturbed normal, and with ``random_plane`` a random
    plane).

    With ``full`` every plane is scored against every source. Otherwise a pixel's planes
    are scored only against its active sources ``S[y, x]`` (the bits of the ``nact``
    sources that matched its best plane best, when that plane was scored against more),
    a neighbour's plane against the neighbour's active sources too: the matching views
    of a surface change little from one iteration to the next, and a source left out
    only makes a plane look worse, never better."""
    h, w = D.shape
    ns = ks.shape[0]
    every = (1 << ns) - 1
    idmin = 1.0 / dmin
    idmax = 1.0 / dmax
    for k in nb.prange(h):
        y = _row(k, h)
        scratch, win, xs, ys = _row_buffers(ns, radius, step)
        nrm = np.empty(3)
        best = np.empty(5)  # cost, depth, normal of the best plane so far
        for x in range((y + colour) % 2, w, 2):
            s0 = stats[y, x, 0]
            ma = stats[y, x, 1] / s0
            if stats[y, x, 2] / s0 - ma * ma < min_var:
                continue  # a textureless window: every plane costs the same
            _window(x, y, ref, wts, radius, step, win, xs, ys)
            _load(best, C, D, N, y, x)
            own = every if full else S[y, x]
            bm = S[y, x]
            rx = kinv[0, 0] * x + kinv[0, 1] * y + kinv[0, 2]
            ry = kinv[1, 0] * x + kinv[1, 1] * y + kinv[1, 2]
            rz = kinv[2, 0] * x + kinv[2, 1] * y + kinv[2, 2]
            # propagation: in each direction, the cheapest of the neighbours at 1, 3, 5
            for dirn in range(4):
                qx = -1
                qy = -1
                qc = 1e30
                for dist in (1, 3, 5):
                    cx = x + (dist if dirn == 0 else (-dist if dirn == 1 else 0))
                    cy = y + (dist if dirn == 2 else (-dist if dirn == 3 else 0))
                    if 0 <= cx < w and 0 <= cy < h and C[cy, cx] < qc:
                        qc = C[cy, cx]
                        qx = cx
                        qy = cy
                if qx < 0:
                    continue
                m0 = N[qy, qx, 0]
                m1 = N[qy, qx, 1]
                m2 = N[qy, qx, 2]
                d = _carried(D, N, qx, qy, kinv, rx, ry, rz)
                if d < dmin or d > dmax:
                    continue
                if (abs(d - best[1]) < 1e-3 * best[1]
                        and m0 * best[2] + m1 * best[3] + m2 * best[4] > 0.9995):
                    continue  # the plane this pixel has (within 0.1 % and 1.8 degrees)
                mask = every if full else own | S[qy, qx]
                if _keep_better(_cost(x, y, d, m0, m1, m2, scratch, win, xs, ys, stats, src,
                                      sizes, kinv, kr, ks, rs, ts, hm, min_var, top_k, geom,
                                      sdepth, max_reproj, mask),
                                d, m0, m1, m2, best):
                    bm = _best_sources(scratch, ns, nact)
            if not full:
                own = bm
            # refinement: perturbed depth and normal, perturbed normal, a random plane
            pix = x * 65536 + y
            for trial in range(3 if random_plane else 2):
                base = 2 + 4 * trial
                if trial == 2:
                    u = _uniform(seed, pix, it, base)
                    d = 1.0 / (idmax + u * (idmin - idmax))
                    _random_normal(seed, x, y, it, base + 1, kinv, nrm)
                    m0 = nrm[0]
                    m1 = nrm[1]
                    m2 = nrm[2]
                else:
                    d, m0, m1, m2 = _perturbed(best, perturb, trial == 0, seed, pix, x, y, it,
                                               base, kinv, nrm)
                    if m0 * rx + m1 * ry + m2 * rz > 0:
                        continue
                if d < dmin or d > dmax:
                    continue
                if _keep_better(_cost(x, y, d, m0, m1, m2, scratch, win, xs, ys, stats, src,
                                      sizes, kinv, kr, ks, rs, ts, hm, min_var, top_k, geom,
                                      sdepth, max_reproj, own),
                                d, m0, m1, m2, best):
                    bm = _best_sources(scratch, ns, nact)
            S[y, x] = bm
            _store(best, C, D, N, y, x)


@nb.njit(parallel=True, cache=True, fastmath=True)
def fill_holes(colour, it, seed, hole, seedable, D0, N0, D, N, C, reach, min_dirs, spread,
               dmin, dmax, ref, wts, stats, src, sizes, kinv, kr, ks, rs, ts, hm, radius, step,
               min_var, top_k, geom, sdepth, max_reproj, perturb):
    """One red-black half-sweep of the second pass over the holes of a depth map.

    Each pixel of this colour where ``hole`` is set tries, in each of the 8 directions,
    the plane of the nearest ``seedable`` pixel (a confirmed depth, or a hole filled by an
    earlier sweep) within ``reach`` pixels, carried to its own ray, then two perturbations
    of its best plane (depth and normal, normal alone); it keeps the cheapest against
    every source, with geometric consistency when ``geom`` > 0. No plane is drawn at
    random: a hole only takes a surface its confirmed neighbours lie on, and only when
    they surround it (seeds in at least ``min_dirs`` of the 8 directions: an edge of a
    surface, where seeds lie on one side only, is left as it was). Seeds are read
    from the snapshot ``D0``, ``N0`` (taken before the sweep), so rows run in parallel
    and the result does not depend on the number of threads."""
    h, w = D.shape
    ns = ks.shape[0]
    every = (1 << ns) - 1
    for k in nb.prange(h):
        y = _row(k, h)
        scratch, win, xs, ys = _row_buffers(ns, radius, step)
        nrm = np.empty(3)
        best = np.empty(5)
        qs = np.empty((8, 2), np.int64)  # each direction's seed pixel (-1: none)
        tried = np.empty((8, 4))  # the seed planes tried: depth, normal
        sd = np.empty(8)  # each direction's seed depth on this pixel's ray (-1: none)
        for x in range((y + colour) % 2, w, 2):
            if not hole[y, x]:
                continue
            s0 = stats[y, x, 0]
            ma = stats[y, x, 1] / s0
            if stats[y, x, 2] / s0 - ma * ma < min_var:
                continue
            _window(x, y, ref, wts, radius, step, win, xs, ys)
            _load(best, C, D, N, y, x)
            rx = kinv[0, 0] * x + kinv[0, 1] * y + kinv[0, 2]
            ry = kinv[1, 0] * x + kinv[1, 1] * y + kinv[1, 2]
            rz = kinv[2, 0] * x + kinv[2, 1] * y + kinv[2, 2]
            found = 0
            for dirn in range(8):
                dx = (1, -1, 0, 0, 1, 1, -1, -1)[dirn]
                dy = (0, 0, 1, -1, 1, -1, 1, -1)[dirn]
                qs[dirn, 0] = -1
                for dist in range(1, reach + 1):
                    qx = x + dx * dist
                    qy = y + dy * dist
                    if qx < 0 or qy < 0 or qx >= w or qy >= h:
                        break
                    if seedable[qy, qx]:
                        qs[dirn, 0] = qx
                        qs[dirn, 1] = qy
                        found += 1
                        break
            if found < min_dirs:
                continue
            lo = 1e30
            hi = 0.0
            for dirn in range(8):
                qx = qs[dirn, 0]
                qy = qs[dirn, 1]
                sd[dirn] = -1.0
                if qx < 0:
                    continue
                d = _carried(D0, N0, qx, qy, kinv, rx, ry, rz)
                sd[dirn] = d
                lo = min(lo, d)
                hi = max(hi, d)
            if hi > lo * (1.0 + spread):
                continue
            ntried = 0
            for dirn in range(8):
                d = sd[dirn]
                if d < dmin or d > dmax:
                    continue
                qx = qs[dirn, 0]
                qy = qs[dirn, 1]
                m0 = N0[qy, qx, 0]
                m1 = N0[qy, qx, 1]
                m2 = N0[qy, qx, 2]
                same = False
                for j in range(ntried):
                    if (abs(tried[j, 0] - d) < 1e-3 * d and tried[j, 1] * m0 + tried[j, 2] * m1
                            + tried[j, 3] * m2 > 0.999):
                        same = True
                        break
                if same:
                    continue
                tried[ntried, 0] = d
                tried[ntried, 1] = m0
                tried[ntried, 2] = m1
                tried[ntried, 3] = m2
                ntried += 1
                _keep_better(_cost(x, y, d, m0, m1, m2, scratch, win, xs, ys, stats, src,
                                   sizes, kinv, kr, ks, rs, ts, hm, min_var,
                                   top_k, geom, sdepth, max_reproj, every),
                             d, m0, m1, m2, best)
            if best[1] <= 0.0:
                continue  # no seed reached this pixel
            pix = x * 65536 + y
            for trial in range(2):
                d, m0, m1, m2 = _perturbed(best, perturb, trial == 0, seed, pix, x, y, it,
                                           40 + 4 * trial, kinv, nrm)
                if m0 * rx + m1 * ry + m2 * rz > 0 or d < dmin or d > dmax:
                    continue
                _keep_better(_cost(x, y, d, m0, m1, m2, scratch, win, xs, ys, stats, src,
                                   sizes, kinv, kr, ks, rs, ts, hm, min_var,
                                   top_k, geom, sdepth, max_reproj, every),
                             d, m0, m1, m2, best)
            _store(best, C, D, N, y, x)


@nb.njit(cache=True, fastmath=True, inline="always")
def _pixel_into(x, y, z, k, wfc, cfw):
    """Pixel (x, y) at depth z of a camera with intrinsics ``k`` and world_from_cam
    ``wfc`` (4x4), in the frame of another camera (its cam_from_world ``cfw``)."""
    p0 = (x - k[0, 2]) / k[0, 0] * z
    p1 = (y - k[1, 2]) / k[1, 1] * z
    X0 = wfc[0, 0] * p0 + wfc[0, 1] * p1 + wfc[0, 2] * z + wfc[0, 3]
    X1 = wfc[1, 0] * p0 + wfc[1, 1] * p1 + wfc[1, 2] * z + wfc[1, 3]
    X2 = wfc[2, 0] * p0 + wfc[2, 1] * p1 + wfc[2, 2] * z + wfc[2, 3]
    return (cfw[0, 0] * X0 + cfw[0, 1] * X1 + cfw[0, 2] * X2 + cfw[0, 3],
            cfw[1, 0] * X0 + cfw[1, 1] * X1 + cfw[1, 2] * X2 + cfw[1, 3],
            cfw[2, 0] * X0 + cfw[2, 1] * X1 + cfw[2, 2] * X2 + cfw[2, 3])


@nb.njit(cache=True, inline="always")
def static_offset(x, y, u, v, u2, v2):
    """How far (px) the pixel (u, v) where a point of pixel (x, y) falls in another view
    lies from (x, y) itself along the epipolar line, whose direction (u2, v2) - (u, v)
    gives (the point a little deeper); inf when the line is a point. Near 0, the match is
    the one a pattern fixed to the image makes (a backdrop behind a turntable, an overlay,
    a dirty lens): the same content at the same pixels, whatever the depth.

    >>> round(static_offset(10.0, 5.0, 12.0, 5.5, 13.0, 5.5), 3)
    -2.0
    """
    du, dv = u2 - u, v2 - v
    n = np.sqrt(du * du + dv * dv)
    if n < 1e-9:
        return np.inf
    return ((x - u) * du + (y - v) * dv) / n


@nb.njit(parallel=True, cache=True, fastmath=True)
def agree_counts(count, depth, normal, k, wfc, cfw, odepth, onormal, ok, owfc, ocfw,
                 depth_tol, max_reproj, cos_max, static_px):
    """``count[y, x] += 1`` where another view's depth map agrees with this view's depth at
    (x, y): the test of :func:`reconstruct.mvs.fusion.fuse_points` with a relative depth
    tolerance. The point of (x, y) falls on the other view's nearest pixel; that pixel's
    depth gives back a point that must reproject within ``max_reproj`` px of (x, y), at a
    depth within ``depth_tol`` (relative to the other view's), with normals (camera
    frames; ``wfc``, ``cfw``: world_from_cam, cam_from_world 4x4) within ``cos_max``.
    With ``static_px`` > 0 a match at the same pixel does not count: the point falls
    within ``static_px`` of (x, y) along its epipolar line in the other view
    (:func:`static_offset`)."""
    h, w = depth.shape
    oh, ow = odepth.shape
    for y in nb.prange(h):
        for x in range(w):
            z = depth[y, x]
            if z <= 0.0:
                continue
            Y0, Y1, Y2 = _pixel_into(x, y, z, k, wfc, ocfw)
            if Y2 <= 1e-12:
                continue
            uf = ok[0, 0] * Y0 / Y2 + ok[0, 2]
            vf = ok[1, 1] * Y1 / Y2 + ok[1, 2]
            uo = int(np.rint(uf))
            vo = int(np.rint(vf))
            if uo < 0 or vo < 0 or uo >= ow or vo >= oh:
                continue
            if static_px > 0.0:
                W0, W1, W2 = _pixel_into(x, y, 1.01 * z, k, wfc, ocfw)
                if W2 > 1e-12 and abs(static_offset(
                        x, y, uf, vf, ok[0, 0] * W0 / W2 + ok[0, 2],
                        ok[1, 1] * W1 / W2 + ok[1, 2])) < static_px:
                    continue
            d = odepth[vo, uo]
            if d <= 0.0 or abs(Y2 - d) / d > depth_tol:
                continue
            Z0, Z1, Z2 = _pixel_into(uo, vo, d, ok, owfc, cfw)
            Z2 = max(Z2, 1e-12)
            eu = k[0, 0] * Z0 / Z2 + k[0, 2] - x
            ev = k[1, 1] * Z1 / Z2 + k[1, 2] - y
            if eu * eu + ev * ev > max_reproj * max_reproj:
                continue
            c = 0.0  # the normals' cosine, in the world frame
            for r in range(3):
                a = (wfc[r, 0] * normal[y, x, 0] + wfc[r, 1] * normal[y, x, 1]
                     + wfc[r, 2] * normal[y, x, 2])
                b = (owfc[r, 0] * onormal[vo, uo, 0] + owfc[r, 1] * onormal[vo, uo, 1]
                     + owfc[r, 2] * onormal[vo, uo, 2])
                c += a * b
            if c >= cos_max:
                count[y, x] += 1
