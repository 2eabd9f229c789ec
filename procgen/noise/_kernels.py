"""Compiled kernels of the noise family (private): 4-D noise, analytic gradients,
periodic noise and the fused octave loops.

Everything here is numba, inlined into the parallel loops of
:mod:`procgen.noise.fractal`. The 3-D value kernel is :func:`procgen.noise.perlin.noise3`
itself, so one octave of fBm is Perlin bit for bit.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from procgen.noise.perlin import _GX, _GY, _GZ, _fade, _lerp, noise3


def _gradient_table4() -> np.ndarray:
    """The 32 edge midpoints of the 4-cube: one coordinate 0, the others +-1."""
    g = []
    for zero in range(4):
        for s in range(8):
            v = [1.0 if (s >> k) & 1 == 0 else -1.0 for k in range(3)]
            v.insert(zero, 0.0)
            g.append(v)
    return np.array(g)


_G4 = _gradient_table4()
_G4X = np.ascontiguousarray(_G4[:, 0])
_G4Y = np.ascontiguousarray(_G4[:, 1])
_G4Z = np.ascontiguousarray(_G4[:, 2])
_G4W = np.ascontiguousarray(_G4[:, 3])


@nb.njit(inline="always", cache=True)
def _grad4(h, x, y, z, w):
    h = h & 31
    return _G4X[h] * x + _G4Y[h] * y + _G4Z[h] * z + _G4W[h] * w


@nb.njit(inline="always", cache=True)
def noise4(p, x, y, z, w):
    """4-D improved gradient noise (Perlin's construction, 32 gradients); 0 on the lattice."""
    fx = np.floor(x)
    fy = np.floor(y)
    fz = np.floor(z)
    fw = np.floor(w)
    X = np.int64(fx) & 255
    Y = np.int64(fy) & 255
    Z = np.int64(fz) & 255
    W = np.int64(fw) & 255
    x -= fx
    y -= fy
    z -= fz
    w -= fw
    u = _fade(x)
    v = _fade(y)
    s = _fade(z)
    t = _fade(w)
    x1 = x - 1.0
    y1 = y - 1.0
    z1 = z - 1.0
    w1 = w - 1.0
    A = p[X] + Y
    B = p[X + 1] + Y
    AA = p[A] + Z
    AB = p[A + 1] + Z
    BA = p[B] + Z
    BB = p[B + 1] + Z
    AAA = p[AA] + W
    AAB = p[AA + 1] + W
    ABA = p[AB] + W
    ABB = p[AB + 1] + W
    BAA = p[BA] + W
    BAB = p[BA + 1] + W
    BBA = p[BB] + W
    BBB = p[BB + 1] + W
    w0 = _lerp(
        s,
        _lerp(v, _lerp(u, _grad4(p[AAA], x, y, z, w), _grad4(p[BAA], x1, y, z, w)),
              _lerp(u, _grad4(p[ABA], x, y1, z, w), _grad4(p[BBA], x1, y1, z, w))),
        _lerp(v, _lerp(u, _grad4(p[AAB], x, y, z1, w), _grad4(p[BAB], x1, y, z1, w)),
              _lerp(u, _grad4(p[ABB], x, y1, z1, w), _grad4(p[BBB], x1, y1, z1, w))),
    )
    w1v = _lerp(
        s,
        _lerp(v, _lerp(u, _grad4(p[AAA + 1], x, y, z, w1), _grad4(p[BAA + 1], x1, y, z, w1)),
              _lerp(u, _grad4(p[ABA + 1], x, y1, z, w1), _grad4(p[BBA + 1], x1, y1, z, w1))),
        _lerp(v, _lerp(u, _grad4(p[AAB + 1], x, y, z1, w1), _grad4(p[BAB + 1], x1, y, z1, w1)),
              _lerp(u, _grad4(p[ABB + 1], x, y1, z1, w1), _grad4(p[BBB + 1], x1, y1, z1, w1))),
    )
    return _lerp(t, w0, w1v)


@nb.njit(inline="always", cache=True)
def _dfade(t):
    return 30.0 * t * t * (t * (t - 2.0) + 1.0)


@nb.njit(inline="always", cache=True)
def noise3_grad(p, x, y, z):
    """Improved noise and its analytic gradient at one point: ``(n, dn/dx, dn/dy, dn/dz)``."""
    fx = np.floor(x)
    fy = np.floor(y)
    fz = np.floor(z)
    X = np.int64(fx) & 255
    Y = np.int64(fy) & 255
    Z = np.int64(fz) & 255
    x -= fx
    y -= fy
    z -= fz
    u = _fade(x)
    v = _fade(y)
    w = _fade(z)
    du = _dfade(x)
    dv = _dfade(y)
    dw = _dfade(z)
    A = p[X] + Y
    AA = p[A] + Z
    AB = p[A + 1] + Z
    B = p[X + 1] + Y
    BA = p[B] + Z
    BB = p[B + 1] + Z
    # corners a..h = (000, 100, 010, 110, 001, 101, 011, 111), gradient indices
    ha = p[AA] & 15
    hb = p[BA] & 15
    hc = p[AB] & 15
    hd = p[BB] & 15
    he = p[AA + 1] & 15
    hf = p[BA + 1] & 15
    hg = p[AB + 1] & 15
    hh = p[BB + 1] & 15
    x1 = x - 1.0
    y1 = y - 1.0
    z1 = z - 1.0
    va = _GX[ha] * x + _GY[ha] * y + _GZ[ha] * z
    vb = _GX[hb] * x1 + _GY[hb] * y + _GZ[hb] * z
    vc = _GX[hc] * x + _GY[hc] * y1 + _GZ[hc] * z
    vd = _GX[hd] * x1 + _GY[hd] * y1 + _GZ[hd] * z
    ve = _GX[he] * x + _GY[he] * y + _GZ[he] * z1
    vf = _GX[hf] * x1 + _GY[hf] * y + _GZ[hf] * z1
    vg = _GX[hg] * x + _GY[hg] * y1 + _GZ[hg] * z1
    vh = _GX[hh] * x1 + _GY[hh] * y1 + _GZ[hh] * z1
    k1 = vb - va
    k2 = vc - va
    k3 = ve - va
    k4 = va - vb - vc + vd
    k5 = va - vc - ve + vg
    k6 = va - vb - ve + vf
    k7 = -va + vb + vc - vd + ve - vf - vg + vh
    n = va + u * k1 + v * k2 + w * k3 + u * v * k4 + v * w * k5 + w * u * k6 + u * v * w * k7
    uv = u * v
    vw = v * w
    wu = w * u
    uvw = uv * w
    # gradient: interpolated corner gradients + fade derivatives times the value differences
    gx = (_GX[ha] + u * (_GX[hb] - _GX[ha]) + v * (_GX[hc] - _GX[ha]) + w * (_GX[he] - _GX[ha])
          + uv * (_GX[ha] - _GX[hb] - _GX[hc] + _GX[hd])
          + vw * (_GX[ha] - _GX[hc] - _GX[he] + _GX[hg])
          + wu * (_GX[ha] - _GX[hb] - _GX[he] + _GX[hf])
          + uvw * (-_GX[ha] + _GX[hb] + _GX[hc] - _GX[hd] + _GX[he] - _GX[hf] - _GX[hg] + _GX[hh])
          + du * (k1 + v * k4 + w * k6 + vw * k7))
    gy = (_GY[ha] + u * (_GY[hb] - _GY[ha]) + v * (_GY[hc] - _GY[ha]) + w * (_GY[he] - _GY[ha])
          + uv * (_GY[ha] - _GY[hb] - _GY[hc] + _GY[hd])
          + vw * (_GY[ha] - _GY[hc] - _GY[he] + _GY[hg])
          + wu * (_GY[ha] - _GY[hb] - _GY[he] + _GY[hf])
          + uvw * (-_GY[ha] + _GY[hb] + _GY[hc] - _GY[hd] + _GY[he] - _GY[hf] - _GY[hg] + _GY[hh])
          + dv * (k2 + u * k4 + w * k5 + wu * k7))
    gz = (_GZ[ha] + u * (_GZ[hb] - _GZ[ha]) + v * (_GZ[hc] - _GZ[ha]) + w * (_GZ[he] - _GZ[ha])
          + uv * (_GZ[ha] - _GZ[hb] - _GZ[hc] + _GZ[hd])
          + vw * (_GZ[ha] - _GZ[hc] - _GZ[he] + _GZ[hg])
          + wu * (_GZ[ha] - _GZ[hb] - _GZ[he] + _GZ[hf])
          + uvw * (-_GZ[ha] + _GZ[hb] + _GZ[hc] - _GZ[hd] + _GZ[he] - _GZ[hf] - _GZ[hg] + _GZ[hh])
          + dw * (k3 + v * k5 + u * k6 + uv * k7))
    return n, gx, gy, gz


@nb.njit(inline="always", cache=True)
def noise3_periodic(p, x, y, z, px, py):
    """Improved noise with integer periods ``px`` along x and ``py`` along y (both <= 256)."""
    fx = np.floor(x)
    fy = np.floor(y)
    fz = np.floor(z)
    ix = np.int64(fx) % px
    iy = np.int64(fy) % py
    X = ix & 255
    Y = iy & 255
    X1 = ((ix + 1) % px) & 255
    Y1 = ((iy + 1) % py) & 255
    Z = np.int64(fz) & 255
    x -= fx
    y -= fy
    z -= fz
    u = _fade(x)
    v = _fade(y)
    w = _fade(z)
    AA = p[p[p[X] + Y] + Z]
    AB = p[p[p[X] + Y1] + Z]
    BA = p[p[p[X1] + Y] + Z]
    BB = p[p[p[X1] + Y1] + Z]
    AA1 = p[p[p[X] + Y] + Z + 1]
    AB1 = p[p[p[X] + Y1] + Z + 1]
    BA1 = p[p[p[X1] + Y] + Z + 1]
    BB1 = p[p[p[X1] + Y1] + Z + 1]
    x1 = x - 1.0
    y1 = y - 1.0
    z1 = z - 1.0
    h = AA & 15
    ga = _GX[h] * x + _GY[h] * y + _GZ[h] * z
    h = BA & 15
    gb = _GX[h] * x1 + _GY[h] * y + _GZ[h] * z
    h = AB & 15
    gc = _GX[h] * x + _GY[h] * y1 + _GZ[h] * z
    h = BB & 15
    gd = _GX[h] * x1 + _GY[h] * y1 + _GZ[h] * z
    h = AA1 & 15
    ge = _GX[h] * x + _GY[h] * y + _GZ[h] * z1
    h = BA1 & 15
    gf = _GX[h] * x1 + _GY[h] * y + _GZ[h] * z1
    h = AB1 & 15
    gg = _GX[h] * x + _GY[h] * y1 + _GZ[h] * z1
    h = BB1 & 15
    gh = _GX[h] * x1 + _GY[h] * y1 + _GZ[h] * z1
    return _lerp(w, _lerp(v, _lerp(u, ga, gb), _lerp(u, gc, gd)),
                 _lerp(v, _lerp(u, ge, gf), _lerp(u, gg, gh)))


# mode: 0 fBm, 1 turbulence (sum of |noise|), 2 ridged multifractal (Musgrave)
@nb.njit(inline="always", cache=True)
def _octaves(p, x, y, z, w, four, octaves, lac, gain, mode, h_exp, offset, rgain):
    total = 0.0
    amp = 1.0
    weight = 1.0
    for i in range(octaves):
        if four:
            n = noise4(p, x, y, z, w)
        else:
            n = noise3(p, x, y, z)
        if mode == 0:
            total += amp * n
            amp *= gain
        elif mode == 1:
            total += amp * abs(n)
            amp *= gain
        else:
            sig = offset - abs(n)
            sig *= sig
            if i > 0:
                sig *= weight
            total += sig * amp
            weight = min(max(sig * rgain, 0.0), 1.0)
            amp *= h_exp
        x *= lac
        y *= lac
        z *= lac
        w *= lac
    return total


@nb.njit(parallel=True, cache=True)
def octaves_many(p, x, y, z, w, four, octaves, lac, gain, mode, h_exp, offset, rgain, out):
    bad = 0
    for i in nb.prange(x.shape[0]):
        xi = x[i]
        yi = y[i]
        zi = z[i]
        wi = w[i]
        if np.isfinite(xi) and np.isfinite(yi) and np.isfinite(zi) and np.isfinite(wi):
            out[i] = _octaves(p, xi, yi, zi, wi, four, octaves, lac, gain, mode, h_exp, offset,
                              rgain)
        else:
            out[i] = np.nan
            bad += 1
    return bad


@nb.njit(parallel=True, cache=True)
def fbm_grad_many(p, x, y, z, octaves, lac, gain, out):
    """fBm and its analytic gradient: ``out[i] = (value, d/dx, d/dy, d/dz)``."""
    for i in nb.prange(x.shape[0]):
        xi = x[i]
        yi = y[i]
        zi = z[i]
        amp = 1.0
        freq = 1.0
        v = 0.0
        gx = 0.0
        gy = 0.0
        gz = 0.0
        for _ in range(octaves):
            n, nx, ny, nz = noise3_grad(p, xi, yi, zi)
            v += amp * n
            gx += amp * freq * nx
            gy += amp * freq * ny
            gz += amp * freq * nz
            amp *= gain
            freq *= lac
            xi *= lac
            yi *= lac
            zi *= lac
        out[i, 0] = v
        out[i, 1] = gx
        out[i, 2] = gy
        out[i, 3] = gz


@nb.njit(parallel=True, cache=True)
def tileable_many(p, x, y, z, period, octaves, lac, gain, out):
    """Periodic fBm of ``(x, y)`` in the unit square: octave k has period ``period * lac**k``."""
    for i in nb.prange(x.shape[0]):
        per = period
        amp = 1.0
        total = 0.0
        zi = z[i]
        for _ in range(octaves):
            total += amp * noise3_periodic(p, x[i] * per, y[i] * per, zi, per, per)
            amp *= gain
            per *= lac
            zi *= lac
        out[i] = total
