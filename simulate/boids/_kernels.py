"""The compiled kernels of the boids: parameters packed into one array, the grid neighbour
sums and steering of both rule sets, the all-pairs reference sums, and the integration
step. The model and its documentation are :mod:`simulate.boids.flock`, which imports this
module (never the reverse)."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

# --- parameters packed for the kernels -------------------------------------------------
_RS2, _RA2, _RC2, _WS, _WA, _WC, _VMAX, _VMIN, _FMAX, _FOVCOS = range(10)
_WW, _WG, _GX, _GY, _GZ, _NLEAD, _WL, _LDIST, _ZOR2, _ZOO2, _ZOA2 = range(10, 21)
_TURN, _SPEED, _DT, _BOUNDED, _LOX, _LOY, _LOZ, _HIX, _HIY, _HIZ, _MARGIN, _WB = range(21, 33)
_NPARAM = 33


def _pack(p) -> np.ndarray:
    """The fields of ``p`` (a :class:`simulate.boids.flock.BoidParams`) the kernels read,
    squared or in radians as they use them, in one float64 array indexed by the constants
    above."""
    out = np.zeros(_NPARAM)
    out[_RS2] = p.separation_radius ** 2
    out[_RA2] = p.alignment_radius ** 2
    out[_RC2] = p.cohesion_radius ** 2
    out[_WS], out[_WA], out[_WC] = p.separation_weight, p.alignment_weight, p.cohesion_weight
    out[_VMAX], out[_VMIN], out[_FMAX] = p.max_speed, p.min_speed, p.max_force
    out[_FOVCOS] = -2.0 if p.fov_deg >= 360 else math.cos(math.radians(p.fov_deg) / 2)
    out[_WW] = p.wander_weight
    if p.goal is not None:
        out[_WG] = p.goal_weight
        out[_GX:_GZ + 1] = p.goal
    out[_NLEAD], out[_WL], out[_LDIST] = p.leaders, p.leader_weight, p.leader_distance
    out[_ZOR2], out[_ZOO2], out[_ZOA2] = p.zor ** 2, p.zoo ** 2, p.zoa ** 2
    out[_TURN] = math.radians(p.turning_rate_deg) * p.dt
    out[_SPEED], out[_DT] = p.speed, p.dt
    if p.bounds is not None:
        out[_BOUNDED] = 1.0
        out[_LOX:_LOZ + 1] = p.bounds[0]
        out[_HIX:_HIZ + 1] = p.bounds[1]
    out[_MARGIN], out[_WB] = p.bounds_margin, p.bounds_weight
    return out


@nb.njit(cache=True, inline="always")
def _steer_to(dx, dy, dz, vx, vy, vz, vmax, fmax):
    """Truncated steering ``normalize(d) * vmax - v``; zero for a zero ``d``."""
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    if n == 0.0:
        return 0.0, 0.0, 0.0
    sx = dx / n * vmax - vx
    sy = dy / n * vmax - vy
    sz = dz / n * vmax - vz
    m = math.sqrt(sx * sx + sy * sy + sz * sz)
    if m > fmax:
        f = fmax / m
        return sx * f, sy * f, sz * f
    return sx, sy, sz


@nb.njit(cache=True, inline="always")
def _steer_add(ax, ay, az, weight, dx, dy, dz, vx, vy, vz, vmax, fmax):
    """``a + weight * steer_to(d)``: one weighted behaviour added to the steering."""
    sx, sy, sz = _steer_to(dx, dy, dz, vx, vy, vz, vmax, fmax)
    return ax + weight * sx, ay + weight * sy, az + weight * sz


@nb.njit(cache=True, inline="always")
def _bounds_push(x, y, z, P):
    """Inward push, growing linearly from 0 at ``margin`` inside a wall to 1 at it."""
    bx = by = bz = 0.0
    if P[_BOUNDED] > 0:
        m = P[_MARGIN]
        if x < P[_LOX] + m:
            bx += (P[_LOX] + m - x) / m
        if x > P[_HIX] - m:
            bx -= (x - P[_HIX] + m) / m
        if y < P[_LOY] + m:
            by += (P[_LOY] + m - y) / m
        if y > P[_HIY] - m:
            by -= (y - P[_HIY] + m) / m
        if z < P[_LOZ] + m:
            bz += (P[_LOZ] + m - z) / m
        if z > P[_HIZ] - m:
            bz -= (z - P[_HIZ] + m) / m
    return bx, by, bz


@nb.njit(cache=True, inline="always")
def _reynolds_finish(i, k, xs, vs, ws, x, v, P, sep, ali, coh, nsep, nali, ncoh, out):
    """Weighted steering of boid ``i`` (row ``k`` of ``xs, vs, ws, out``) from its
    neighbour sums (shared by both paths); ``x, v`` by id, for the leaders."""
    px, py, pz = xs[k, 0], xs[k, 1], xs[k, 2]
    vx, vy, vz = vs[k, 0], vs[k, 1], vs[k, 2]
    vmax = P[_VMAX]
    fmax = P[_FMAX]
    ax = ay = az = 0.0
    if nsep > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WS], sep[0], sep[1], sep[2], vx, vy, vz, vmax, fmax)
    if nali > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WA], ali[0] / nali, ali[1] / nali, ali[2] / nali,
                                vx, vy, vz, vmax, fmax)
    if ncoh > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WC], coh[0] / ncoh, coh[1] / ncoh, coh[2] / ncoh,
                                vx, vy, vz, vmax, fmax)
    if P[_WW] > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WW], ws[k, 0], ws[k, 1], ws[k, 2],
                                vx, vy, vz, vmax, fmax)
    nlead = np.int64(P[_NLEAD])
    if i < nlead or nlead == 0:
        if P[_WG] > 0:
            ax, ay, az = _steer_add(ax, ay, az, P[_WG], P[_GX] - px, P[_GY] - py, P[_GZ] - pz,
                                    vx, vy, vz, vmax, fmax)
    elif P[_WL] > 0:
        best = -1
        bd = np.inf
        for m in range(nlead):
            dx = x[m, 0] - px
            dy = x[m, 1] - py
            dz = x[m, 2] - pz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < bd:
                bd = d2
                best = m
        lvx, lvy, lvz = v[best, 0], v[best, 1], v[best, 2]
        ls = math.sqrt(lvx * lvx + lvy * lvy + lvz * lvz)
        tx, ty, tz = x[best, 0], x[best, 1], x[best, 2]
        if ls > 0:
            tx -= lvx / ls * P[_LDIST]
            ty -= lvy / ls * P[_LDIST]
            tz -= lvz / ls * P[_LDIST]
        ax, ay, az = _steer_add(ax, ay, az, P[_WL], tx - px, ty - py, tz - pz,
                                vx, vy, vz, vmax, fmax)
    bx, by, bz = _bounds_push(px, py, pz, P)
    out[k, 0] = ax + P[_WB] * fmax * bx
    out[k, 1] = ay + P[_WB] * fmax * by
    out[k, 2] = az + P[_WB] * fmax * bz


@nb.njit(cache=True, inline="always")
def _couzin_finish(k, xs, vs, P, dr, do, da, nr, no, na, out):
    """Desired unit direction of the boid in row ``k`` (zero: keep heading)."""
    dx = dy = dz = 0.0
    if nr > 0:
        dx, dy, dz = dr[0], dr[1], dr[2]
    else:
        on = math.sqrt(do[0] * do[0] + do[1] * do[1] + do[2] * do[2])
        an = math.sqrt(da[0] * da[0] + da[1] * da[1] + da[2] * da[2])
        if no > 0 and on > 0:
            f = 0.5 if (na > 0 and an > 0) else 1.0
            dx += f * do[0] / on
            dy += f * do[1] / on
            dz += f * do[2] / on
        if na > 0 and an > 0:
            f = 0.5 if (no > 0 and on > 0) else 1.0
            dx += f * da[0] / an
            dy += f * da[1] / an
            dz += f * da[2] / an
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    if n > 0:
        dx /= n
        dy /= n
        dz /= n
    bx, by, bz = _bounds_push(xs[k, 0], xs[k, 1], xs[k, 2], P)
    if bx != 0.0 or by != 0.0 or bz != 0.0:
        if n == 0:
            sp = math.sqrt(vs[k, 0] ** 2 + vs[k, 1] ** 2 + vs[k, 2] ** 2)
            if sp > 0:
                dx, dy, dz = vs[k, 0] / sp, vs[k, 1] / sp, vs[k, 2] / sp
        dx += P[_WB] * bx
        dy += P[_WB] * by
        dz += P[_WB] * bz
        n = math.sqrt(dx * dx + dy * dy + dz * dz)
        if n > 0:
            dx /= n
            dy /= n
            dz /= n
    out[k, 0] = dx
    out[k, 1] = dy
    out[k, 2] = dz


@nb.njit(parallel=True, cache=True)
def _gather(x, v, w, order, xs, vs, ws):
    for k in nb.prange(order.shape[0]):
        i = order[k]
        for a in range(3):
            xs[k, a] = x[i, a]
            vs[k, a] = v[i, a]
            ws[k, a] = w[i, a]


@nb.njit(parallel=True, cache=True)
def _scatter(src, order, dst):
    for k in nb.prange(order.shape[0]):
        i = order[k]
        for a in range(3):
            dst[i, a] = src[k, a]


@nb.njit(parallel=True, cache=True, error_model="numpy")
def _steer_grid(x, v, P, couzin, xs, vs, ws, order, cell, dims, start, reach, out):
    """Steering (Reynolds) or desired direction (Couzin) of every boid, on the grid.

    ``xs, vs, ws`` are positions, velocities and wander sorted by cell (``order``), and
    so is ``out``; each boid's neighbours are visited cell by cell, in a fixed order,
    by one thread.
    """
    nx, ny, nz = dims[0], dims[1], dims[2]
    fovcos = P[_FOVCOS]
    rs2, ra2, rc2 = P[_RS2], P[_RA2], P[_RC2]
    zor2, zoo2 = P[_ZOR2], P[_ZOO2]
    if couzin:
        r2max = P[_ZOA2]
    else:
        r2max = max(P[_RS2], max(P[_RA2], P[_RC2]))
    for c in nb.prange(start.shape[0] - 1):
        if start[c] == start[c + 1]:
            continue
        cx0 = c % nx
        cy0 = (c // nx) % ny
        cz0 = c // (nx * ny)
        for k in range(start[c], start[c + 1]):
            i = order[k]
            px, py, pz = xs[k, 0], xs[k, 1], xs[k, 2]
            vx, vy, vz = vs[k, 0], vs[k, 1], vs[k, 2]
            sp = math.sqrt(vx * vx + vy * vy + vz * vz)
            hx = hy = hz = 0.0
            if sp > 0:
                hx, hy, hz = vx / sp, vy / sp, vz / sp
            look = fovcos > -1.0 and sp > 0
            a0 = a1 = a2 = b0 = b1 = b2 = c0 = c1 = c2 = 0.0
            na = nb_ = nc = 0
            gx0 = max(cx0 - reach, 0)
            gx1 = min(cx0 + reach, nx - 1)
            for gz in range(max(cz0 - reach, 0), min(cz0 + reach + 1, nz)):
                for gy in range(max(cy0 - reach, 0), min(cy0 + reach + 1, ny)):
                    # cells along x are consecutive in the sorted order: one contiguous run
                    g = nx * (gy + ny * gz)
                    for kk in range(start[g + gx0], start[g + gx1 + 1]):
                        if kk == k:
                            continue
                        dx = xs[kk, 0] - px
                        dy = xs[kk, 1] - py
                        dz = xs[kk, 2] - pz
                        r2 = dx * dx + dy * dy + dz * dz
                        if r2 >= r2max:
                            continue
                        r = math.sqrt(r2)
                        if look and hx * dx + hy * dy + hz * dz < fovcos * r:
                            continue
                        if couzin:
                            if r2 < zor2:
                                if r > 0:
                                    a0 -= dx / r
                                    a1 -= dy / r
                                    a2 -= dz / r
                                na += 1
                            elif r2 < zoo2:
                                wx, wy, wz = vs[kk, 0], vs[kk, 1], vs[kk, 2]
                                wn = math.sqrt(wx * wx + wy * wy + wz * wz)
                                if wn > 0:
                                    b0 += wx / wn
                                    b1 += wy / wn
                                    b2 += wz / wn
                                nb_ += 1
                            else:
                                c0 += dx / r
                                c1 += dy / r
                                c2 += dz / r
                                nc += 1
                        else:
                            if r2 < rs2 and r2 > 0:
                                a0 -= dx / r2
                                a1 -= dy / r2
                                a2 -= dz / r2
                                na += 1
                            if r2 < ra2:
                                b0 += vs[kk, 0]
                                b1 += vs[kk, 1]
                                b2 += vs[kk, 2]
                                nb_ += 1
                            if r2 < rc2:
                                c0 += dx
                                c1 += dy
                                c2 += dz
                                nc += 1
            if couzin:
                _couzin_finish(k, xs, vs, P, (a0, a1, a2), (b0, b1, b2), (c0, c1, c2), na, nb_,
                               nc, out)
            else:
                _reynolds_finish(i, k, xs, vs, ws, x, v, P, (a0, a1, a2), (b0, b1, b2),
                                 (c0, c1, c2), na, nb_, nc, out)


@nb.njit(parallel=True, cache=True, error_model="numpy")
def _finish_all(x, v, wander, P, couzin, sums, counts, out):
    """Apply the per-boid rules to neighbour sums computed elsewhere (the reference)."""
    for i in nb.prange(x.shape[0]):
        r = (sums[i, 0, 0], sums[i, 0, 1], sums[i, 0, 2])
        o = (sums[i, 1, 0], sums[i, 1, 1], sums[i, 1, 2])
        t = (sums[i, 2, 0], sums[i, 2, 1], sums[i, 2, 2])
        if couzin:
            _couzin_finish(i, x, v, P, r, o, t, counts[i, 0], counts[i, 1], counts[i, 2], out)
        else:
            _reynolds_finish(i, i, x, v, wander, x, v, P, r, o, t, counts[i, 0], counts[i, 1],
                             counts[i, 2], out)


def _sums_reference(x, v, P, couzin, block=512):
    """Neighbour sums ``(n, 3 rules, 3)`` and counts ``(n, 3)`` over all n^2 pairs (numpy)."""
    n = len(x)
    sums = np.zeros((n, 3, 3))
    counts = np.zeros((n, 3), np.int64)
    sp = np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])
    h = np.divide(v, sp[:, None], out=np.zeros_like(v), where=sp[:, None] > 0)
    vs_n = h  # unit velocities (Couzin orientation)
    r2max = P[_ZOA2] if couzin else max(P[_RS2], P[_RA2], P[_RC2])
    for a0 in range(0, n, block):
        a1 = min(a0 + block, n)
        d = x[None, :, :] - x[a0:a1, None, :]
        dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
        r2 = dx * dx + dy * dy + dz * dz
        r = np.sqrt(r2)
        m = r2 < r2max
        m[np.arange(a1 - a0), np.arange(a0, a1)] = False
        hb = h[a0:a1]
        look = (P[_FOVCOS] > -1.0) & (sp[a0:a1] > 0)
        dot = hb[:, 0:1] * dx + hb[:, 1:2] * dy + hb[:, 2:3] * dz
        m &= ~(look[:, None] & (dot < P[_FOVCOS] * r))
        rs = np.where(r > 0, r, 1.0)
        if couzin:
            mr = m & (r2 < P[_ZOR2])
            mo = m & ~mr & (r2 < P[_ZOO2])
            ma = m & ~mr & ~mo
            sums[a0:a1, 0] = -np.einsum("ij,ijk->ik", (mr & (r > 0)) / rs, d)
            sums[a0:a1, 1] = mo.astype(float) @ vs_n
            sums[a0:a1, 2] = np.einsum("ij,ijk->ik", ma / rs, d)
        else:
            mr = m & (r2 < P[_RS2]) & (r2 > 0)
            mo = m & (r2 < P[_RA2])
            ma = m & (r2 < P[_RC2])
            sums[a0:a1, 0] = -np.einsum("ij,ijk->ik", mr / np.where(r2 > 0, r2, 1.0), d)
            sums[a0:a1, 1] = mo.astype(float) @ v
            sums[a0:a1, 2] = np.einsum("ij,ijk->ik", ma.astype(float), d)
        counts[a0:a1, 0] = mr.sum(axis=1)
        counts[a0:a1, 1] = mo.sum(axis=1)
        counts[a0:a1, 2] = ma.sum(axis=1)
    return sums, counts



@nb.njit(inline="always", cache=True)
def _reflect(p, v, lo, hi):
    """Mirror a coordinate that left ``[lo, hi]`` back inside; its velocity points in."""
    if p < lo:
        return min(2 * lo - p, hi), abs(v)
    if p > hi:
        return max(2 * hi - p, lo), -abs(v)
    return p, v

@nb.njit(parallel=True, cache=True, error_model="numpy")
def _integrate(x, v, steer, noise, P, couzin, xn, vn):
    """Advance every boid one step: truncate steering (Reynolds) or turn (Couzin), move,
    reflect at the world box."""
    dt = P[_DT]
    for i in nb.prange(x.shape[0]):
        vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
        if couzin:
            s = math.sqrt(vx * vx + vy * vy + vz * vz)
            if s > 0:
                hx, hy, hz = vx / s, vy / s, vz / s
            else:
                hx, hy, hz = 1.0, 0.0, 0.0
            dx, dy, dz = steer[i, 0], steer[i, 1], steer[i, 2]
            if dx == 0.0 and dy == 0.0 and dz == 0.0:
                dx, dy, dz = hx, hy, hz
            # angular noise: a perpendicular Gaussian kick of the desired direction
            gx, gy, gz = noise[i, 0], noise[i, 1], noise[i, 2]
            gd = gx * dx + gy * dy + gz * dz
            dx += gx - gd * dx
            dy += gy - gd * dy
            dz += gz - gd * dz
            n = math.sqrt(dx * dx + dy * dy + dz * dz)
            dx /= n
            dy /= n
            dz /= n
            c = min(max(hx * dx + hy * dy + hz * dz, -1.0), 1.0)
            ang = math.acos(c)
            if ang > P[_TURN]:
                # rotate h toward d by the turning limit, in their common plane
                px, py, pz = dx - c * hx, dy - c * hy, dz - c * hz
                pn = math.sqrt(px * px + py * py + pz * pz)
                if pn < 1e-12:  # opposite: any perpendicular will do
                    if abs(hx) < 0.9:
                        px, py, pz = 0.0, -hz, hy
                    else:
                        px, py, pz = -hz, 0.0, hx
                    pn = math.sqrt(px * px + py * py + pz * pz)
                px /= pn
                py /= pn
                pz /= pn
                t = P[_TURN]
                dx = math.cos(t) * hx + math.sin(t) * px
                dy = math.cos(t) * hy + math.sin(t) * py
                dz = math.cos(t) * hz + math.sin(t) * pz
            sp = P[_SPEED]
            vx, vy, vz = dx * sp, dy * sp, dz * sp
        else:
            ax, ay, az = steer[i, 0], steer[i, 1], steer[i, 2]
            m = math.sqrt(ax * ax + ay * ay + az * az)
            if m > P[_FMAX]:
                f = P[_FMAX] / m
                ax *= f
                ay *= f
                az *= f
            vx += ax * dt
            vy += ay * dt
            vz += az * dt
            s = math.sqrt(vx * vx + vy * vy + vz * vz)
            if s > P[_VMAX]:
                f = P[_VMAX] / s
                vx *= f
                vy *= f
                vz *= f
            elif s < P[_VMIN]:
                if s > 0:
                    f = P[_VMIN] / s
                    vx *= f
                    vy *= f
                    vz *= f
                else:
                    vx = P[_VMIN]
        px = x[i, 0] + vx * dt
        py = x[i, 1] + vy * dt
        pz = x[i, 2] + vz * dt
        if P[_BOUNDED] > 0:
            px, vx = _reflect(px, vx, P[_LOX], P[_HIX])
            py, vy = _reflect(py, vy, P[_LOY], P[_HIY])
            pz, vz = _reflect(pz, vz, P[_LOZ], P[_HIZ])
        xn[i, 0], xn[i, 1], xn[i, 2] = px, py, pz
        vn[i, 0], vn[i, 1], vn[i, 2] = vx, vy, vz
