"""numba kernels of the LiDAR simulator: packing a block's sub-rays for Embree and
turning Embree's answers into sub-ray ranges and energies, in one pass each."""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, parallel=True)
def pack_subrays(pos, d, offsets, half, rays):
    """``rays (n*s, 6) float32``: each pulse's origin and its ``s`` sub-ray directions in
    a cone of half-angle ``half`` about ``d (n, 3)`` (offsets in units of ``half``)."""
    n = d.shape[0]
    s = offsets.shape[0]
    ca, sa = np.empty(s), np.empty(s)
    c, sn = np.zeros(s), np.zeros(s)
    for i in range(s):
        r = np.sqrt(offsets[i, 0] ** 2 + offsets[i, 1] ** 2)
        ca[i], sa[i] = np.cos(r * half), np.sin(r * half)
        if r > 0:
            c[i], sn[i] = offsets[i, 0] / r, offsets[i, 1] / r
    for p in nb.prange(n):
        dx, dy, dz = d[p, 0], d[p, 1], d[p, 2]
        if abs(dz) < 0.9:            # e1 = a x d with a = z, else a = x
            ax, ay, az = 0.0, 0.0, 1.0
        else:
            ax, ay, az = 1.0, 0.0, 0.0
        e1x, e1y, e1z = ay * dz - az * dy, az * dx - ax * dz, ax * dy - ay * dx
        nn = np.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
        e1x, e1y, e1z = e1x / nn, e1y / nn, e1z / nn
        e2x, e2y, e2z = dy * e1z - dz * e1y, dz * e1x - dx * e1z, dx * e1y - dy * e1x
        for i in range(s):
            q = p * s + i
            u, v = c[i] * sa[i], sn[i] * sa[i]
            rays[q, 0], rays[q, 1], rays[q, 2] = pos[p, 0], pos[p, 1], pos[p, 2]
            rays[q, 3] = dx * ca[i] + e1x * u + e2x * v
            rays[q, 4] = dy * ca[i] + e1y * u + e2y * v
            rays[q, 5] = dz * ca[i] + e1z * u + e2z * v


@nb.njit(cache=True, parallel=True)
def hits_to_energy(t_hit, gid, pid, normals, rays, weights, lut, face_offset, refl,
                   min_range, R, E, obj, face):
    """Per sub-ray: range ``R`` (inf on a miss or nearer than ``min_range``), returned
    energy ``E = w rho cos / R^2``, object index ``obj`` (-1) and flat face ``face``."""
    m = t_hit.shape[0]
    s = weights.shape[0]
    for q in nb.prange(m):
        t = t_hit[q]
        if not np.isfinite(t) or t < min_range:
            R[q] = np.inf
            E[q] = 0.0
            obj[q] = -1
            face[q] = 0
            continue
        o = lut[gid[q]]
        nx, ny, nz = normals[q, 0], normals[q, 1], normals[q, 2]
        c = abs(nx * rays[q, 3] + ny * rays[q, 4] + nz * rays[q, 5])
        c /= max(np.sqrt(nx * nx + ny * ny + nz * nz), 1e-12)
        R[q] = t
        E[q] = weights[q % s] * refl[o] * c / (float(t) * float(t))
        obj[q] = o
        face[q] = face_offset[o] + pid[q]


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


@nb.njit(cache=True, inline="always")
def _mix(x):
    """splitmix64's finaliser: a well-mixed 64-bit word of ``x``."""
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


@nb.njit(cache=True, inline="always")
def _uniform(h, k):
    """The ``k``-th uniform [0, 1) of the stream of cell hash ``h``."""
    return float(_mix(h + np.uint64(k + 1) * _GOLDEN) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@nb.njit(cache=True, inline="always")
def _cell_hash(i, j, k, seed):
    h = _mix(np.uint64(seed) ^ np.uint64(0x632BE59BD9B4E019))
    h = _mix(h ^ np.uint64(i & 0xFFFFFFFFFFFF))
    h = _mix(h ^ np.uint64(j & 0xFFFFFFFFFFFF) * _GOLDEN)
    return _mix(h ^ np.uint64(k & 0xFFFFFFFFFFFF) * _M1)


@nb.njit(cache=True)
def _cell_leaves(o, d, t0, t1, ci, cj, ck, cell, lam, radius, seed, best, mu):
    """The nearest hit within ``[t0, t1]`` of the ray ``o + t d`` (unit ``d``) on the
    leaves of lattice cell ``(ci, cj, ck)`` if nearer than ``best``: ``(t, |cos|)``, else
    ``(best, mu)`` as given. The cell holds Poisson(``lam``) discs of ``radius`` centred
    at uniform points of it (at least ``radius`` inside its floor and ceiling: a leaf
    stays in its layer of cells), their normals uniform on the sphere; its hash draws
    them, so every ray meets the same leaves. A larger ``lam`` keeps the leaves of a
    smaller one and adds. A disc's points lie within ``radius`` of its centre, so a centre
    farther than that from the ray, or along it outside ``[t0, min(t1, best)]``, is passed
    over before its normal is drawn (with a margin: no hit is ever lost)."""
    h = _cell_hash(ci, cj, ck, seed)
    u = _uniform(h, 0)
    p = np.exp(-lam)
    acc = p
    n = 0
    while u > acc and n < 256:
        n += 1
        p *= lam / n
        acc += p
    span = cell - 2.0 * radius
    reach = radius * 1.001 + 1e-9
    for q in range(n):
        b = 1 + 5 * q
        cx = (ci + _uniform(h, b)) * cell
        cy = (cj + _uniform(h, b + 1)) * cell
        cz = ck * cell + radius + span * _uniform(h, b + 2)
        wx, wy, wz = cx - o[0], cy - o[1], cz - o[2]
        tc = wx * d[0] + wy * d[1] + wz * d[2]
        if tc + reach < t0 or tc - reach > t1 or tc - reach >= best:
            continue
        px, py, pz = wy * d[2] - wz * d[1], wz * d[0] - wx * d[2], wx * d[1] - wy * d[0]
        if px * px + py * py + pz * pz > reach * reach:
            continue
        z = 2.0 * _uniform(h, b + 3) - 1.0
        phi = 2.0 * np.pi * _uniform(h, b + 4)
        s = np.sqrt(max(0.0, 1.0 - z * z))
        nx, ny, nz = s * np.cos(phi), s * np.sin(phi), z
        den = d[0] * nx + d[1] * ny + d[2] * nz
        if abs(den) < 1e-12:
            continue
        t = ((cx - o[0]) * nx + (cy - o[1]) * ny + (cz - o[2]) * nz) / den
        if t < t0 or t > t1 or t >= best:
            continue
        hx, hy, hz = o[0] + t * d[0] - cx, o[1] + t * d[1] - cy, o[2] + t * d[2] - cz
        if hx * hx + hy * hy + hz * hz <= radius * radius:
            best, mu = t, abs(den)
    return best, mu


_BOX_CELLS = 16   # cells a layer's stretch may span (with its reach) to be read as a box


@nb.njit(cache=True)
def _layer_leaves(o, d, ta, tb, kz, cell, lam, radius, seed):
    """The nearest leaf hit of the ray for ``t`` in ``[ta, tb]``, the stretch within the
    layer of cells ``kz``: the leaves of every cell whose leaves may reach the stretch. A
    steep stretch spans few cells, read as the box of cells within a leaf's radius of its
    ends; a long one is walked cell by cell (Amanatides and Woo 1987, in x and y), each
    with its eight neighbours (a leaf reaches over its cell's sides)."""
    best, mu = np.inf, 0.0
    px, py = o[0] + ta * d[0], o[1] + ta * d[1]
    qx, qy = o[0] + tb * d[0], o[1] + tb * d[1]
    reach = radius * 1.001 + 1e-9
    i0 = int(np.floor((min(px, qx) - reach) / cell))
    i1 = int(np.floor((max(px, qx) + reach) / cell))
    j0 = int(np.floor((min(py, qy) - reach) / cell))
    j1 = int(np.floor((max(py, qy) + reach) / cell))
    if (i1 - i0 + 1) * (j1 - j0 + 1) <= _BOX_CELLS:
        for ci in range(i0, i1 + 1):
            for cj in range(j0, j1 + 1):
                best, mu = _cell_leaves(o, d, ta, tb, ci, cj, kz, cell, lam, radius, seed,
                                        best, mu)
        return best, mu
    ix, iy = int(np.floor(px / cell)), int(np.floor(py / cell))
    sx, sy = 0, 0
    tx, ty, dx, dy = np.inf, np.inf, np.inf, np.inf
    if d[0] > 0:
        sx, tx, dx = 1, ta + ((ix + 1) * cell - px) / d[0], cell / d[0]
    elif d[0] < 0:
        sx, tx, dx = -1, ta + (ix * cell - px) / d[0], -cell / d[0]
    if d[1] > 0:
        sy, ty, dy = 1, ta + ((iy + 1) * cell - py) / d[1], cell / d[1]
    elif d[1] < 0:
        sy, ty, dy = -1, ta + (iy * cell - py) / d[1], -cell / d[1]
    while True:
        for ni in range(-1, 2):
            for nj in range(-1, 2):
                best, mu = _cell_leaves(o, d, ta, tb, ix + ni, iy + nj, kz, cell, lam,
                                        radius, seed, best, mu)
        if tx < ty:
            if tx > tb:
                break
            ix += sx
            tx += dx
        else:
            if ty > tb:
                break
            iy += sy
            ty += dy
    return best, mu


@nb.njit(cache=True, parallel=True)
def leaf_hits(o, d, t0, t1, lad, cell, leaf_area, seed, t_out, mu_out):
    """Per ray ``o + t d`` (unit ``d``): the first leaf met for ``t`` in ``[t0, t1]`` where
    the leaf area density is ``lad`` (m²/m³; discs of area ``leaf_area`` in the cells of
    a lattice of side ``cell`` anchored at the origin, :func:`_cell_leaves`), layer of
    cells by layer of cells in the ray's order (:func:`_layer_leaves`). ``t_out`` (inf:
    none) and ``mu_out``, the cosine between the ray and the leaf's normal."""
    radius = np.sqrt(leaf_area / np.pi)
    for r in nb.prange(o.shape[0]):
        t_out[r], mu_out[r] = np.inf, 0.0
        if lad[r] <= 0.0 or not t1[r] > t0[r]:
            continue
        lam = lad[r] * cell ** 3 / leaf_area
        ta, b = t0[r], t1[r]
        kz = int(np.floor((o[r, 2] + ta * d[r, 2]) / cell))
        while ta <= b:
            if d[r, 2] > 0:
                te = ((kz + 1) * cell - o[r, 2]) / d[r, 2]
            elif d[r, 2] < 0:
                te = (kz * cell - o[r, 2]) / d[r, 2]
            else:
                te = np.inf
            te = min(te, b)
            t, mu = _layer_leaves(o[r], d[r], ta, te, kz, cell, lam, radius, seed)
            if t < np.inf:
                t_out[r], mu_out[r] = t, mu
                break
            if te >= b:
                break
            ta = te
            kz += 1 if d[r, 2] > 0 else -1
