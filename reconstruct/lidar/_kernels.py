"""numba kernels of the ground filter: Axelsson's TIN densification on a Delaunay
triangulation kept up to date by insertion (Bowyer-Watson), and the robust lower surface.

Rebuilding the triangulation of every ground point and locating every candidate in it
again at every pass cost O(n) per pass however few points joined; here a pass re-locates
only the candidates whose triangle a new point replaced (a walk from that triangle's
successor) and inserts the points that joined into their cavities. The ground only grows
inside the seeds' convex hull (a candidate outside it is never tested), so the hull never
changes and insertion needs no hull update.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, inline="always")
def _orient(ax, ay, bx, by, cx, cy):
    """Twice the signed area of (a, b, c): > 0 counter-clockwise."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@nb.njit(cache=True)
def _incircle(xy, a, b, c, px, py):
    """> 0 when (px, py) lies inside the circumcircle of the counter-clockwise (a, b, c)."""
    adx, ady = xy[a, 0] - px, xy[a, 1] - py
    bdx, bdy = xy[b, 0] - px, xy[b, 1] - py
    cdx, cdy = xy[c, 0] - px, xy[c, 1] - py
    ad = adx * adx + ady * ady
    bd = bdx * bdx + bdy * bdy
    cd = cdx * cdx + cdy * cdy
    return (adx * (bdy * cd - bd * cdy) - ady * (bdx * cd - bd * cdx)
            + ad * (bdx * cdy - bdy * cdx))


@nb.njit(cache=True)
def _walk(xy, tv, tn, t, px, py, work):
    """The triangle holding (px, py), walking from triangle ``t``; -1 outside the hull.

    A visibility walk: step across the first edge (starting at a rotating edge, which
    rules out cycles in degenerate cases) that has the point strictly on its outer side;
    a point on an edge belongs to either triangle.
    """
    steps = 0
    rot = 0
    limit = 4 * tv.shape[0] + 64
    work[1] += 1
    while steps < limit:
        steps += 1
        work[2] += 1
        moved = False
        for jj in range(3):
            j = (jj + rot) % 3
            a = tv[t, (j + 1) % 3]
            b = tv[t, (j + 2) % 3]
            if _orient(xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], px, py) < 0.0:
                t = tn[t, j]
                if t < 0:
                    return -1
                moved = True
                break
        if not moved:
            return t
        rot += 1
    return -2  # no convergence: the caller searches every triangle


@nb.njit(cache=True)
def _locate(xy, tv, tn, alive, repl, t, px, py, work):
    """The live triangle holding (px, py), from a hint ``t`` that may have been replaced."""
    while not alive[t]:
        t = repl[t]
    s = _walk(xy, tv, tn, t, px, py, work)
    if s != -2:
        return s
    for u in range(tv.shape[0]):  # brute force, never seen but kept for safety
        if alive[u]:
            a, b, c = tv[u, 0], tv[u, 1], tv[u, 2]
            if (_orient(xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], px, py) >= 0.0
                    and _orient(xy[b, 0], xy[b, 1], xy[c, 0], xy[c, 1], px, py) >= 0.0
                    and _orient(xy[c, 0], xy[c, 1], xy[a, 0], xy[a, 1], px, py) >= 0.0):
                return u
    return -1


@nb.njit(cache=True)
def _grow(a, n):
    out = np.empty((n,) + a.shape[1:], a.dtype)
    out[:a.shape[0]] = a
    return out


@nb.njit(cache=True)
def _insert(xy, tv, tn, alive, repl, nt, t0, pi, cav, edges):
    """Insert point ``pi`` lying in live triangle ``t0`` (Bowyer-Watson).

    Returns the new triangle count, or -1 when the point was not inserted: it coincides
    with a corner (Qhull leaves such a duplicate out too) or rounding made its cavity
    not star-shaped. ``cav`` and ``edges`` are scratch buffers.
    """
    px, py = xy[pi, 0], xy[pi, 1]
    for j in range(3):
        v = tv[t0, j]
        if xy[v, 0] == px and xy[v, 1] == py:
            return -1
    # the cavity: the triangles whose circumcircle holds the point, grown from t0
    nc = 0
    cav[nc] = t0
    nc += 1
    alive[t0] = False  # marks "in the cavity" while it grows; restored on failure
    k = 0
    while k < nc:
        t = cav[k]
        k += 1
        for j in range(3):
            u = tn[t, j]
            if u < 0 or not alive[u]:
                continue
            if _incircle(xy, tv[u, 0], tv[u, 1], tv[u, 2], px, py) > 0.0:
                if nc >= cav.shape[0]:
                    for m in range(nc):
                        alive[cav[m]] = True
                    return -1
                cav[nc] = u
                alive[u] = False
                nc += 1
    # its boundary: edges (a, b, outer triangle) with the cavity on their left
    ne = 0
    for m in range(nc):
        t = cav[m]
        for j in range(3):
            u = tn[t, j]
            if u >= 0 and not alive[u]:
                # inside the cavity, or a triangle dead before (never: dead ones have no
                # live neighbours pointing at them)
                inside = False
                for mm in range(nc):
                    if cav[mm] == u:
                        inside = True
                        break
                if inside:
                    continue
            a = tv[t, (j + 1) % 3]
            b = tv[t, (j + 2) % 3]
            o = _orient(xy[a, 0], xy[a, 1], xy[b, 0], xy[b, 1], px, py)
            if o <= 0.0:
                if u < 0 and o == 0.0:
                    continue  # the point lies on the hull's edge: that edge splits in two
                for mm in range(nc):
                    alive[cav[mm]] = True
                return -1
            if ne >= edges.shape[0]:
                for mm in range(nc):
                    alive[cav[mm]] = True
                return -1
            edges[ne, 0] = a
            edges[ne, 1] = b
            edges[ne, 2] = u
            ne += 1
    # new triangles (a, b, point), neighbours: opposite a the one starting at b, opposite
    # b the one ending at a, opposite the point the outer triangle
    first = nt
    for e in range(ne):
        t = nt + e
        a, b, u = edges[e, 0], edges[e, 1], edges[e, 2]
        tv[t, 0], tv[t, 1], tv[t, 2] = a, b, pi
        tn[t, 2] = u
        tn[t, 0] = -1
        tn[t, 1] = -1
        for f in range(ne):
            if edges[f, 0] == b:
                tn[t, 0] = first + f
            if edges[f, 1] == a:
                tn[t, 1] = first + f
        if u >= 0:  # the outer triangle's edge (b, a) now faces t
            for j in range(3):
                if tv[u, (j + 1) % 3] == b and tv[u, (j + 2) % 3] == a:
                    tn[u, j] = t
        alive[t] = True
        repl[t] = t
    for m in range(nc):
        repl[cav[m]] = first
    return nt + ne


@nb.njit(cache=True)
def _vertex_normals(p, tv, alive, nt, vn):
    """Unit upward normals of the TIN's vertices: their triangles' normals weighted by
    area (``vn`` filled; vertices of no triangle get 0)."""
    vn[:] = 0.0
    for t in range(nt):
        if not alive[t]:
            continue
        a, b, c = tv[t, 0], tv[t, 1], tv[t, 2]
        ux, uy, uz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
        wx, wy, wz = p[c, 0] - p[a, 0], p[c, 1] - p[a, 1], p[c, 2] - p[a, 2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        if nz < 0:
            nx, ny, nz = -nx, -ny, -nz
        for v in (a, b, c):
            vn[v, 0] += nx
            vn[v, 1] += ny
            vn[v, 2] += nz
    for v in range(vn.shape[0]):
        m = np.sqrt(vn[v, 0] ** 2 + vn[v, 1] ** 2 + vn[v, 2] ** 2)
        if m > 0:
            vn[v, 0] /= m
            vn[v, 1] /= m
            vn[v, 2] /= m


@nb.njit(cache=True)
def densify(p, tv0, tn0, ground, cand, loc, angle, distance, offset, passes, slope_gain,
            slope_rise, local, angle_below, work):
    """Axelsson's densification on the triangulation ``tv0``/``tn0`` (counter-clockwise
    corners, neighbours opposite each corner, -1 on the hull) of the seeds.

    ``p (n, 3)`` has its x and y centred; ``ground (n,)`` is updated in place;
    ``cand`` are the candidates in a space-filling order, ``loc`` their triangles in the
    seeds' triangulation (-1 outside it). ``slope_rise`` >= 90 leaves the slope term's
    slope the triangle's. ``work`` (4,) counts the passes, the walks, the triangles they
    stepped through, and the points inserted. A candidate below its triangle's plane is
    held to ``angle_below`` instead of ``angle`` (degrees; the slope term added to both).
    """
    nt = tv0.shape[0]
    cap = nt + 8 * len(cand) + 64
    tv = np.empty((cap, 3), np.int64)
    tn = np.empty((cap, 3), np.int64)
    tv[:nt] = tv0
    tn[:nt] = tn0
    alive = np.zeros(cap, np.bool_)
    alive[:nt] = True
    repl = np.arange(cap)
    vn = np.zeros((p.shape[0], 3))
    seed_slope = np.full(len(cand), 90.0)  # the seeds' slope under each candidate
    todo = np.empty(len(cand), np.bool_)
    for i in range(len(cand)):
        todo[i] = loc[i] >= 0
        if todo[i]:
            seed_slope[i] = _slope(p, tv, loc[i])
    joins = np.empty(len(cand), np.int64)
    for _ in range(passes):
        work[0] += 1
        if local:
            _vertex_normals(p, tv, alive, nt, vn)
        nj = _pass(p, tv, tn, alive, repl, vn, cand, loc, todo, seed_slope, joins, angle,
                   distance, offset, slope_gain, slope_rise, local, angle_below, work)
        if nj == 0:
            break
        tv, tn, alive, repl, nt = _insert_all(p, tv, tn, alive, repl, nt, ground, cand, loc,
                                              todo, joins[:nj], work)


@nb.njit(cache=True)
def _pass(p, tv, tn, alive, repl, vn, cand, loc, todo, seed_slope, joins, angle, distance,
          offset, slope_gain, slope_rise, local, angle_below, work):
    """One densification pass: the candidates that join (their positions in ``cand``
    written to ``joins``, their count returned), each tested against the triangle
    holding it."""
    xy = p[:, :2]
    tan_max = np.tan(np.radians(angle))
    nj = 0
    prev = -1
    for i in range(len(cand)):
        if not todo[i]:
            continue
        c = cand[i]
        t = loc[i]
        if not alive[t]:
            # walk from the last candidate's triangle (they come in a space-filling
            # order, so it is near), else from what replaced this one
            t = _locate(xy, tv, tn, alive, repl, prev if prev >= 0 else t,
                        xy[c, 0], xy[c, 1], work)
            if t < 0:
                todo[i] = False
                continue
            loc[i] = t
        prev = t
        a, b, e = tv[t, 0], tv[t, 1], tv[t, 2]
        ux, uy, uz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
        wx, wy, wz = p[e, 0] - p[a, 0], p[e, 1] - p[a, 1], p[e, 2] - p[a, 2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        m = np.sqrt(nx * nx + ny * ny + nz * nz)
        if m == 0.0:
            continue
        nx, ny, nz = nx / m, ny / m, nz / m
        sd = ((p[c, 0] - p[a, 0]) * nx + (p[c, 1] - p[a, 1]) * ny
              + (p[c, 2] - p[a, 2]) * nz) * (1.0 if nz > 0 else -1.0)  # + above
        d = abs(sd)
        if not d < distance:
            continue
        if d < offset:
            joins[nj] = i
            nj += 1
            continue
        r = np.inf
        near = a
        for v in (a, b, e):
            rv = np.sqrt((xy[c, 0] - xy[v, 0]) ** 2 + (xy[c, 1] - xy[v, 1]) ** 2)
            if rv < r:
                r = rv
                near = v
        d_angle = d
        if local:
            dl = abs((p[c, 0] - p[near, 0]) * vn[near, 0]
                     + (p[c, 1] - p[near, 1]) * vn[near, 1]
                     + (p[c, 2] - p[near, 2]) * vn[near, 2])
            d_angle = min(d, dl)
        base = angle if sd >= 0.0 else angle_below
        tan_a = tan_max if sd >= 0.0 else np.tan(np.radians(min(angle_below, 89.0)))
        if slope_gain > 0:
            s = np.degrees(np.arccos(min(abs(nz), 1.0)))
            if slope_rise < 90.0:
                s = min(s, seed_slope[i] + slope_rise)
            tan_a = np.tan(np.radians(min(base + slope_gain * s, 89.0)))
        if d_angle < tan_a * r:
            joins[nj] = i
            nj += 1
    return nj


@nb.njit(cache=True)
def _insert_all(p, tv, tn, alive, repl, nt, ground, cand, loc, todo, joins, work):
    """The candidates ``joins`` made ground and inserted into the triangulation (its
    arrays grown when full); returns the arrays and the triangle count."""
    xy = p[:, :2]
    cav = np.empty(4096, np.int64)
    edges = np.empty((4096, 3), np.int64)
    for i in joins:
        c = cand[i]
        ground[c] = True
        todo[i] = False
        t = _locate(xy, tv, tn, alive, repl, loc[i], xy[c, 0], xy[c, 1], work)
        if t < 0:
            continue
        if nt + cav.shape[0] + 2 > tv.shape[0]:
            size = 2 * tv.shape[0]
            tv = _grow(tv, size)
            tn = _grow(tn, size)
            alive2 = np.zeros(size, np.bool_)
            alive2[:alive.shape[0]] = alive
            alive = alive2
            repl2 = np.arange(size)
            repl2[:repl.shape[0]] = repl
            repl = repl2
        r = _insert(xy, tv, tn, alive, repl, nt, t, c, cav, edges)
        if r >= 0:
            nt = r
            work[3] += 1
    return tv, tn, alive, repl, nt


@nb.njit(cache=True)
def _slope(p, tv, t):
    """Slope in degrees of triangle ``t``."""
    a, b, e = tv[t, 0], tv[t, 1], tv[t, 2]
    ux, uy, uz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1], p[b, 2] - p[a, 2]
    wx, wy, wz = p[e, 0] - p[a, 0], p[e, 1] - p[a, 1], p[e, 2] - p[a, 2]
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    m = np.sqrt(nx * nx + ny * ny + nz * nz)
    if m == 0.0:
        return 90.0
    return np.degrees(np.arccos(min(abs(nz) / m, 1.0)))


@nb.njit(cache=True)
def _solve(m, v):
    """``m x = v`` for a small dense ``m`` (Gaussian elimination, partial pivoting);
    both overwritten, ``x`` left in ``v``."""
    k = m.shape[0]
    for c in range(k):
        piv = c
        for r in range(c + 1, k):
            if abs(m[r, c]) > abs(m[piv, c]):
                piv = r
        if piv != c:
            for j in range(k):
                m[c, j], m[piv, j] = m[piv, j], m[c, j]
            v[c], v[piv] = v[piv], v[c]
        if m[c, c] == 0.0:
            v[c] = 0.0
            continue
        for r in range(c + 1, k):
            f = m[r, c] / m[c, c]
            if f != 0.0:
                for j in range(c, k):
                    m[r, j] -= f * m[c, j]
                v[r] -= f * v[c]
    for c in range(k - 1, -1, -1):
        s = v[c]
        for j in range(c + 1, k):
            s -= m[c, j] * v[j]
        v[c] = s / m[c, c] if m[c, c] != 0.0 else 0.0


@nb.njit(cache=True)
def _robust_fit(a, zz, w, ns, iterations, certain, ramp, ridge, m, v):
    """Weighted least squares of ``zz[:ns]`` on the columns of ``a[:ns]`` (``v`` the
    coefficients), ``iterations`` times, the weights ``w`` after each fit
    ``clip((certain - e) / ramp, 0, 1)`` of its residuals (Kraus and Pfeifer's asymmetric
    weights; ``w`` starts at 1). ``m`` is scratch, ``ridge`` added to its diagonal."""
    p = v.shape[0]
    for j in range(ns):
        w[j] = 1.0
    for _ in range(iterations):
        for r in range(p):
            v[r] = 0.0
            for c in range(p):
                m[r, c] = ridge if r == c else 0.0
        for j in range(ns):
            if w[j] == 0.0:
                continue
            for r in range(p):
                wr = w[j] * a[j, r]
                v[r] += wr * zz[j]
                for c in range(r, p):
                    m[r, c] += wr * a[j, c]
        for r in range(p):
            for c in range(r):
                m[r, c] = m[c, r]
        _solve(m, v)
        for j in range(ns):
            e = zz[j]
            for r in range(p):
                e -= a[j, r] * v[r]
            w[j] = min(max((certain - e) / ramp, 0.0), 1.0)


@nb.njit(cache=True)
def lower_surface(xy, z, nb_idx, rows, iterations, certain, ramp, ridge, out, spread):
    """Height at each point of ``rows`` of the robust quadratic through its neighbours.

    ``nb_idx (n, k)`` are each point's neighbours (itself left out); the quadratic
    ``z(dx, dy)`` about the point is fitted by least squares ``iterations`` times, the
    weights after each fit ``clip((certain - e) / ramp, 0, 1)`` of its residuals ``e``
    (Kraus and Pfeifer's asymmetric weights); ``out[i]`` its value at the point and
    ``spread[i]`` the weighted RMS of the residuals of the neighbours below it (the
    weights of the last fit): how far the ground itself strays from the quadratic there.
    Below only: vegetation over the ground lies above the fit, and would widen it.
    """
    k = nb_idx.shape[1]
    a = np.empty((k, 6))
    w = np.empty(k)
    zz = np.empty(k)
    m = np.empty((6, 6))
    v = np.empty(6)
    for ii in range(len(rows)):
        i = rows[ii]
        for j in range(k):
            q = nb_idx[i, j]
            dx, dy = xy[q, 0] - xy[i, 0], xy[q, 1] - xy[i, 1]
            a[j, 0], a[j, 1], a[j, 2] = 1.0, dx, dy
            a[j, 3], a[j, 4], a[j, 5] = dx * dx, dx * dy, dy * dy
            zz[j] = z[q]
        _robust_fit(a, zz, w, k, iterations, certain, ramp, ridge, m, v)
        out[i] = v[0]
        sw = 0.0
        se = 0.0
        for j in range(k):
            e = zz[j]
            for r in range(6):
                e -= a[j, r] * v[r]
            if e < 0.0:
                sw += w[j]
                se += w[j] * e * e
        spread[i] = np.sqrt(se / sw) if sw > 0.0 else 0.0


@nb.njit(cache=True)
def edge_surface(xy, z, nb_idx, rows, directions, min_side, drop, share, iterations,
                 certain, ramp, ridge, out):
    """For each point of ``rows``: the least distance from it to the robust plane of its
    neighbours on one side of it (``directions`` half-discs, ``(dx, dy) . u >= 0``, of
    ``min_side`` points or more) where at least ``share`` of the other side's points lie
    more than ``drop`` below that plane; inf when no side is such. A point on the top
    edge of a cliff lies on the plane of the ground behind it, and the cliff's foot far
    below it; a shrub lies on no side's plane, and grass or low shrubs on a bank drop
    less than their own height."""
    k = nb_idx.shape[1]
    a = np.empty((k, 3))
    zz = np.empty(k)
    w = np.empty(k)
    m = np.empty((3, 3))
    v = np.empty(3)
    for ii in range(len(rows)):
        i = rows[ii]
        best = np.inf
        for d in range(directions):
            ang = 2.0 * np.pi * d / directions
            ux, uy = np.cos(ang), np.sin(ang)
            ns = 0
            for j in range(k):
                q = nb_idx[i, j]
                dx, dy = xy[q, 0] - xy[i, 0], xy[q, 1] - xy[i, 1]
                if dx * ux + dy * uy >= 0.0:
                    a[ns, 0], a[ns, 1], a[ns, 2] = 1.0, dx, dy
                    zz[ns] = z[q]
                    ns += 1
            if ns < min_side:
                continue
            _robust_fit(a, zz, w, ns, iterations, certain, ramp, ridge, m, v)
            # the other side must drop: most of its points well below the side's plane
            below = 0
            other = 0
            for j in range(k):
                q = nb_idx[i, j]
                dx, dy = xy[q, 0] - xy[i, 0], xy[q, 1] - xy[i, 1]
                if dx * ux + dy * uy < 0.0:
                    other += 1
                    if z[q] - v[0] - dx * v[1] - dy * v[2] < -drop:
                        below += 1
            if other > 0 and below >= share * other:
                best = min(best, abs(z[i] - v[0]))
        out[i] = best
