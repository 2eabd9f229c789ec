"""Compiled kernels of the ray-cast renderer (private): camera rays, Embree's answer
resolved to objects and refined in float64, fBm albedo, and the direct light of point
and directional lights.

Each kernel is one pass over the rays, parallel over cores, writing into arrays the
caller owns: the renderer's numpy glue (fancy indexing, per-object masks, temporary
copies) cost more than the casts themselves (see ``docs/materials.md``, the render
profile). :mod:`acquire.render.renderer` keeps the general paths (distorted cameras, image and
other solid textures, glossy materials, lasers and projectors) and calls these where
they apply; the results agree with those paths to rounding (``tests/test_render_fast.py``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from procgen.noise.perlin import noise3

# light kinds
POINT, DIRECTIONAL = 0, 1
# albedo codes
OTHER, CONSTANT, FBM = 0, 1, 2


BLOCK = 2048  # rays per block of the scattered parallel loops


@nb.njit(inline="always", cache=True)
def n_blocks(n):  # pragma: no cover
    """The number of blocks of :data:`BLOCK` rays in ``n`` rays, for a parallel loop
    ``for k in prange(n_blocks(n)): lo, hi = block_rows(k, n)``, which takes the blocks in
    a scattered order. numba splits a ``prange`` into one contiguous range per thread,
    and a view's hits are not spread evenly over its rows (the sky at the top, the ground
    at the bottom): the thread with the ground did 2.6 times the other's work and the fBm
    took 1.4x its balanced time."""
    return (n + BLOCK - 1) // BLOCK


@nb.njit(inline="always", cache=True)
def block_rows(k, n):  # pragma: no cover
    """The rows ``[lo, hi)`` of the ``k``-th block of the scattered order: block
    ``k g mod m`` of the ``m`` blocks, ``g`` coprime with ``m`` near its golden section,
    so each thread's contiguous run of ``k`` visits blocks all over the rows."""
    m = n_blocks(n)
    g = max(int(m * 0.6180339887498949), 1)
    while m > 1:
        a, b = g, m
        while b:
            a, b = b, a % b
        if a == 1:
            break
        g += 1
    blk = (k * g) % m
    return blk * BLOCK, min(n, (blk + 1) * BLOCK)


@nb.njit(parallel=True, cache=True)
def pinhole_rays(H, W, s, fx, fy, cx, cy, R, d):  # pragma: no cover
    """Directions of the rays of an undistorted camera (rotation ``R`` world from
    camera) through the s x s sub-pixel centres of every pixel, in
    :meth:`acquire.camera.Camera.pixel_grid`'s order (row-major pixels, then sub-rows,
    then sub-columns), scaled to z = 1 in the camera as
    :meth:`~acquire.camera.Camera.rays`."""
    ss = s * s
    for p in nb.prange(H * W):
        v = p // W
        u = p - v * W
        for k in range(ss):
            r = k // s
            c = k - r * s
            x = (u + ((c + 0.5) / s - 0.5) - cx) / fx
            y = (v + ((r + 0.5) / s - 0.5) - cy) / fy
            i = p * ss + k
            for a in range(3):
                d[i, a] = R[a, 0] * x + R[a, 1] * y + R[a, 2]


@nb.njit(parallel=True, cache=True)
def pack_rays(o, d, rays):  # pragma: no cover
    """Embree's float32 ``(n, 6)`` rays from float64 origins and directions."""
    for i in nb.prange(o.shape[0]):
        for a in range(3):
            rays[i, a] = o[i, a]
            rays[i, 3 + a] = d[i, a]


@nb.njit(parallel=True, cache=True)
def resolve_hits(t_hit, gid, pid, lut, face_offset, hit, obj, tri, face):  # pragma: no cover
    """Embree's answer per ray: hit or not, the object (``lut`` of geometry ids), the
    triangle of that object and the face in the scene's flat arrays."""
    for i in nb.prange(t_hit.shape[0]):
        if np.isfinite(t_hit[i]):
            ob = lut[gid[i]]
            hit[i] = True
            obj[i] = ob
            tri[i] = pid[i]
            face[i] = face_offset[ob] + pid[i]
        else:
            hit[i] = False
            obj[i] = -1
            tri[i] = -1
            face[i] = 0


@nb.njit(parallel=True, cache=True, fastmath=True)   # 20 % faster, within 1e-14
def albedo_fast(points, hit, obj, code, Tinv, scale, contrast, base, perms, octaves,
                out):  # pragma: no cover
    """Albedo of the hits on objects whose material is constant (``code`` 1) or the
    'fbm' solid texture (2): the base colour modulated by ``clip(0.5 + 0.5 contrast t,
    0.02, 1)``, ``t`` the fBm at the object-frame point times ``scale``, normalised by
    its octave amplitudes and times 1.8 (:func:`acquire.render.materials._fbm_texture`). Other
    objects (0) are left to the caller."""
    norm = 2.0 - 0.5 ** (octaves - 1)
    nrays = points.shape[0]
    for blk in nb.prange(n_blocks(nrays)):
        lo, hi = block_rows(blk, nrays)
        for i in range(lo, hi):
            _albedo_one(i, points, hit, obj, code, Tinv, scale, contrast, base, perms,
                        octaves, norm, out)


@nb.njit(inline="always", cache=True, fastmath=True)
def _albedo_one(i, points, hit, obj, code, Tinv, scale, contrast, base, perms, octaves, norm,
                out):  # pragma: no cover
    if not hit[i]:
        return
    k = obj[i]
    c = code[k]
    if c == CONSTANT:
        for a in range(3):
            out[i, a] = base[k, a]
    elif c == FBM:
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        x = (Tinv[k, 0, 0] * px + Tinv[k, 0, 1] * py + Tinv[k, 0, 2] * pz
             + Tinv[k, 0, 3]) * scale[k]
        y = (Tinv[k, 1, 0] * px + Tinv[k, 1, 1] * py + Tinv[k, 1, 2] * pz
             + Tinv[k, 1, 3]) * scale[k]
        z = (Tinv[k, 2, 0] * px + Tinv[k, 2, 1] * py + Tinv[k, 2, 2] * pz
             + Tinv[k, 2, 3]) * scale[k]
        p = perms[k]
        total = 0.0
        amp = 1.0
        for _ in range(octaves):
            total += amp * noise3(p, x, y, z)
            amp *= 0.5
            x *= 2.0
            y *= 2.0
            z *= 2.0
        f = 0.5 + 0.5 * contrast[k] * (total / norm * 1.8)
        f = min(max(f, 0.02), 1.0)
        for a in range(3):
            out[i, a] = f * base[k, a]


@nb.njit(parallel=True, cache=True)
def light_irradiance(points, normals, hit, kind, vec, intensity, irr):  # pragma: no cover
    """Unshadowed irradiance (per unit colour) of a point light at ``vec`` or a
    directional one travelling along ``vec`` (unit), as :mod:`acquire.render.lights`."""
    nrays = points.shape[0]
    for blk in nb.prange(n_blocks(nrays)):
        lo, hi = block_rows(blk, nrays)
        for i in range(lo, hi):
            if not hit[i]:
                irr[i] = 0.0
                continue
            if kind == POINT:
                d0 = vec[0] - points[i, 0]
                d1 = vec[1] - points[i, 1]
                d2 = vec[2] - points[i, 2]
                r2 = d0 * d0 + d1 * d1 + d2 * d2
                cos = ((d0 * normals[i, 0] + d1 * normals[i, 1] + d2 * normals[i, 2])
                       / np.sqrt(max(r2, 1e-300)))
                irr[i] = intensity * max(cos, 0.0) / max(r2, 1e-12)
            else:
                cos = -(normals[i, 0] * vec[0] + normals[i, 1] * vec[1] + normals[i, 2] * vec[2])
                irr[i] = intensity * max(cos, 0.0)


@nb.njit(parallel=True, cache=True)
def light_shadow_rays(points, geo, rows, kind, vec, far, offset, rays):  # pragma: no cover
    """float32 shadow rays from the points ``rows`` to the light (t = 1 at the light or
    ``far`` away for a directional one), nudged by ``offset`` off the surface on the
    side facing the light (as :func:`acquire.render.renderer.visibility`)."""
    for j in nb.prange(rows.shape[0]):
        i = rows[j]
        if kind == POINT:
            d0 = vec[0] - points[i, 0]
            d1 = vec[1] - points[i, 1]
            d2 = vec[2] - points[i, 2]
        else:
            d0 = -vec[0] * far
            d1 = -vec[1] * far
            d2 = -vec[2] * far
        c = geo[i, 0] * d0 + geo[i, 1] * d1 + geo[i, 2] * d2
        k = offset * (1.0 if c > 0 else (-1.0 if c < 0 else 0.0))
        for a in range(3):
            rays[j, a] = points[i, a] + k * geo[i, a]
        rays[j, 3] = d0
        rays[j, 4] = d1
        rays[j, 5] = d2


@nb.njit(parallel=True, cache=True)
def add_light(E, rows, irr, occluded, color):  # pragma: no cover
    """``E[rows] += irr * color`` where the shadow ray was not occluded."""
    for j in nb.prange(rows.shape[0]):
        if occluded[j]:
            continue
        i = rows[j]
        for a in range(3):
            E[i, a] += irr[i] * color[a]


@nb.njit(parallel=True, cache=True)
def lambert_out(hit, alb, E, background, out):  # pragma: no cover
    """Radiance of Lambertian hits, ``albedo * E``; the background on misses (``out``
    may be ``E``)."""
    for i in nb.prange(hit.shape[0]):
        for a in range(3):
            out[i, a] = alb[i, a] * E[i, a] if hit[i] else background[a]


@nb.njit(parallel=True, cache=True)
def cosine_bounce(normals, obj, rows, view_dirs, u, lam, alb, wi, pdf, refl):  # pragma: no cover
    """Cosine-weighted directions at the hits ``rows`` (of ``normals`` and ``obj``) on
    Lambertian objects (``lam[obj]``), from the uniform numbers ``u``, as
    :func:`acquire.render.brdf.sample_mixture` with no specular lobe draws them (Malley, in the
    frame of :func:`acquire.render.brdf._basis`): ``wi``, its density ``max(n.wi, 0) / pi`` and
    the reflectance ``pi f`` (the albedo where ``wi`` is above the surface and the view
    ray ``view_dirs`` arrives from above). All but ``normals`` and ``obj`` are per row."""
    for k in nb.prange(rows.shape[0]):
        i = rows[k]
        if not lam[obj[i]]:
            continue
        n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
        if abs(n0) < 0.9:   # t = n x (1, 0, 0)
            t0, t1, t2 = 0.0, n2, -n1
        else:               # t = n x (0, 1, 0)
            t0, t1, t2 = -n2, 0.0, n0
        tl = np.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        t0, t1, t2 = t0 / tl, t1 / tl, t2 / tl
        b0 = n1 * t2 - n2 * t1
        b1 = n2 * t0 - n0 * t2
        b2 = n0 * t1 - n1 * t0
        r = np.sqrt(u[k, 0])
        phi = 2.0 * np.pi * u[k, 1]
        lx, ly, lz = r * np.cos(phi), r * np.sin(phi), np.sqrt(max(1.0 - u[k, 0], 0.0))
        w0 = t0 * lx + b0 * ly + n0 * lz
        w1 = t1 * lx + b1 * ly + n1 * lz
        w2 = t2 * lx + b2 * ly + n2 * lz
        wi[k, 0], wi[k, 1], wi[k, 2] = w0, w1, w2
        ci = w0 * n0 + w1 * n1 + w2 * n2
        pdf[k] = max(ci, 0.0) / np.pi
        up = ci > 0 and (view_dirs[k, 0] * n0 + view_dirs[k, 1] * n1
                         + view_dirs[k, 2] * n2) < 0
        for a in range(3):
            refl[k, a] = alb[k, a] if up else 0.0


@nb.njit(parallel=True, cache=True)
def bounce_start(points, geo, normals, rows, wi, pdf, refl, thin, eps, go, origin, weight,
                 cos_out):  # pragma: no cover
    """Which drawn directions continue (density, reflectance and cosine above zero, and
    above the geometric surface unless the sheet is thin), the ray origins nudged
    ``eps`` off the surface on ``wi``'s side, and each ray's ``f cos / pdf`` weight
    (``refl / pi * cos / pdf``). ``rows`` index ``points``, ``geo`` and ``normals``; the
    other arrays are per row."""
    for k in nb.prange(rows.shape[0]):
        i = rows[k]
        c = wi[k, 0] * normals[i, 0] + wi[k, 1] * normals[i, 1] + wi[k, 2] * normals[i, 2]
        if thin[k]:
            c = abs(c)
        g = wi[k, 0] * geo[i, 0] + wi[k, 1] * geo[i, 1] + wi[k, 2] * geo[i, 2]
        side = 1.0 if g > 0 else (-1.0 if g < 0 else 0.0)
        cos_out[k] = c
        go[k] = (pdf[k] > 0 and c > 0 and (thin[k] or side > 0)
                 and (refl[k, 0] > 0 or refl[k, 1] > 0 or refl[k, 2] > 0))
        for a in range(3):
            origin[k, a] = points[i, a] + eps * side * geo[i, a]
            weight[k, a] = refl[k, a] / np.pi * (c / pdf[k]) if go[k] else 0.0


@nb.njit(parallel=True, cache=True)
def add_indirect(out, out_rows, went, weight, L, hit):  # pragma: no cover
    """``out[out_rows[went[j]]] += weight[j] * L[j]`` for the bounce rays ``j`` that hit
    (``out_rows`` without repeats)."""
    for j in nb.prange(went.shape[0]):
        if not hit[j]:
            continue
        i = out_rows[went[j]]
        for a in range(3):
            out[i, a] += weight[j, a] * L[j, a]


@nb.njit(parallel=True, cache=True)
def centre_from_rays(hit, obj, tri, ss, analytic, face_offset, c_hit, c_obj, c_tri, c_face,
                     todo):  # pragma: no cover
    """Per pixel, from its ``ss`` consecutive rays: if all miss, the centre ray misses;
    if all hit one triangle, or one object with an analytic shape (``analytic[obj]``
    non-zero), the centre ray hits it (the first ray's triangle); otherwise ``todo``."""
    for p in nb.prange(c_hit.shape[0]):
        b = p * ss
        first = hit[b]
        same = True
        for k in range(1, ss):
            j = b + k
            if hit[j] != first:
                same = False
                break
            if first and (obj[j] != obj[b] or (analytic[obj[b]] == 0 and tri[j] != tri[b])):
                same = False
                break
        todo[p] = not same
        c_hit[p] = first and same
        c_obj[p] = obj[b] if (first and same) else -1
        c_tri[p] = tri[b] if (first and same) else -1
        c_face[p] = face_offset[obj[b]] + tri[b] if (first and same) else 0


@nb.njit(parallel=True, cache=True)
def pixel_mean(rad, ss, out):  # pragma: no cover
    """``out[p] = mean of rad[p * ss : (p + 1) * ss]`` in float32: the ``ss``
    consecutive samples of each pixel averaged (``rad.reshape(-1, ss, 3).mean(1)``)."""
    for p in nb.prange(out.shape[0]):
        for a in range(3):
            acc = 0.0
            for k in range(ss):
                acc += rad[p * ss + k, a]
            out[p, a] = acc / ss


@nb.njit(parallel=True, cache=True)
def ground_truth(hit, t, obj, normals, points, ids, depth, oid, nrm, pts):  # pragma: no cover
    """A view's ground truth from its centre rays, in float32: z-depth (0 on a miss;
    ``t`` is z-depth for camera rays), object ids (``ids[obj]``, -1 on a miss), normals
    and points (zeros on a miss)."""
    nrays = hit.shape[0]
    for blk in nb.prange(n_blocks(nrays)):
        lo, hi = block_rows(blk, nrays)
        for i in range(lo, hi):
            depth[i] = t[i] if hit[i] else 0.0
            oid[i] = ids[obj[i]] if hit[i] else -1
            for a in range(3):
                nrm[i, a] = normals[i, a]
                pts[i, a] = points[i, a]
