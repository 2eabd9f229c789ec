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
