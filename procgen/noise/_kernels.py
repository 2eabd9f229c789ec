"""Compiled kernels of the noise family (private): 4-D noise, analytic gradients,
periodic noise and the fused octave loops.

Everything here is numba, inlined into the parallel loops of
:mod:`procgen.noise.fractal`. The 3-D value kernel is :func:`procgen.noise.perlin.noise3`
itself, so one octave of fBm is Perlin bit for bit.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from procgen.noise.perlin import (
    _GX,
    _GY,
    _GZ,
    _cell,
    _corner_values,
    _hashes,
    _lerp,
    _trilerp,
    noise3,
)


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
def _corner_values4(p, h, W, x, y, z, w):
    """Gradient dot offset at the 8 corners of a 3-D cell on the hyperplane of ``W``."""
    x1 = x - 1.0
    y1 = y - 1.0
    z1 = z - 1.0
    return (_grad4(p[h[0] + W], x, y, z, w), _grad4(p[h[1] + W], x1, y, z, w),
            _grad4(p[h[2] + W], x, y1, z, w), _grad4(p[h[3] + W], x1, y1, z, w),
            _grad4(p[h[4] + W], x, y, z1, w), _grad4(p[h[5] + W], x1, y, z1, w),
            _grad4(p[h[6] + W], x, y1, z1, w), _grad4(p[h[7] + W], x1, y1, z1, w))


@nb.njit(inline="always", cache=True)
def noise4(p, x, y, z, w):
    """4-D improved gradient noise (Perlin's construction, 32 gradients); 0 on the lattice."""
    ix, x, u = _cell(x)
    iy, y, v = _cell(y)
    iz, z, s = _cell(z)
    iw, w, t = _cell(w)
    X = ix & 255
    Y = iy & 255
    W = iw & 255
    h = _hashes(p, X, X + 1, Y, Y + 1, iz & 255)
    w0 = _trilerp(u, v, s, _corner_values4(p, h, W, x, y, z, w))
    w1 = _trilerp(u, v, s, _corner_values4(p, h, W + 1, x, y, z, w - 1.0))
    return _lerp(t, w0, w1)


@nb.njit(inline="always", cache=True)
def _dfade(t):
    return 30.0 * t * t * (t * (t - 2.0) + 1.0)


@nb.njit(inline="always", cache=True)
def _bilerp(s, t, a, b, c, d):
    ab = a + s * (b - a)
    cd = c + s * (d - c)
    return ab + t * (cd - ab)


@nb.njit(inline="always", cache=True)
def _cell_gradient(g, c, u, v, w, du, dv, dw):
    """The one gradient of improved noise in a cell: the corner gradients (indices
    ``g & 15``, corners ordered as :func:`procgen.noise.perlin._hashes`) interpolated,
    plus the fade derivatives times the corner-value differences ``c``.
    Returns ``(n, dn/dx, dn/dy, dn/dz)``."""
    gx = _trilerp(u, v, w, (_GX[g[0] & 15], _GX[g[1] & 15], _GX[g[2] & 15], _GX[g[3] & 15],
                            _GX[g[4] & 15], _GX[g[5] & 15], _GX[g[6] & 15], _GX[g[7] & 15]))
    gy = _trilerp(u, v, w, (_GY[g[0] & 15], _GY[g[1] & 15], _GY[g[2] & 15], _GY[g[3] & 15],
                            _GY[g[4] & 15], _GY[g[5] & 15], _GY[g[6] & 15], _GY[g[7] & 15]))
    gz = _trilerp(u, v, w, (_GZ[g[0] & 15], _GZ[g[1] & 15], _GZ[g[2] & 15], _GZ[g[3] & 15],
                            _GZ[g[4] & 15], _GZ[g[5] & 15], _GZ[g[6] & 15], _GZ[g[7] & 15]))
    # x: differences b-a, d-c, f-e, h-g bilinear in (v, w); y and z alike
    gx += du * _bilerp(v, w, c[1] - c[0], c[3] - c[2], c[5] - c[4], c[7] - c[6])
    gy += dv * _bilerp(u, w, c[2] - c[0], c[3] - c[1], c[6] - c[4], c[7] - c[5])
    gz += dw * _bilerp(u, v, c[4] - c[0], c[5] - c[1], c[6] - c[2], c[7] - c[3])
    return _trilerp(u, v, w, c), gx, gy, gz


@nb.njit(inline="always", cache=True)
def noise3_grad(p, x, y, z):
    """Improved noise and its analytic gradient at one point: ``(n, dn/dx, dn/dy, dn/dz)``."""
    ix, x, u = _cell(x)
    iy, y, v = _cell(y)
    iz, z, w = _cell(z)
    h = _hashes(p, ix & 255, (ix & 255) + 1, iy & 255, (iy & 255) + 1, iz & 255)
    du = _dfade(x)
    dv = _dfade(y)
    dw = _dfade(z)
    return _cell_gradient(h, _corner_values(h, x, y, z), u, v, w, du, dv, dw)


@nb.njit(inline="always", cache=True)
def curl_potentials(p, x, y, z):
    """Two decorrelated improved noises and their gradients from one lattice walk.

    The corner hashes are Perlin's (``p`` a :func:`perm_table`); the first noise takes its
    gradient index from the low four bits of each hash — it is :func:`noise3` exactly —
    and the second from the high four bits. Over a permutation of 0..255 the two nibbles
    are uniform and independent, so the second noise is another improved noise on the
    same lattice, for the price of eight more dot products instead of a second walk.

    Returns ``(n1, dn1/dx, dn1/dy, dn1/dz, n2, dn2/dx, dn2/dy, dn2/dz)``.
    """
    ix, x, u = _cell(x)
    iy, y, v = _cell(y)
    iz, z, w = _cell(z)
    h = _hashes(p, ix & 255, (ix & 255) + 1, iy & 255, (iy & 255) + 1, iz & 255)
    du = _dfade(x)
    dv = _dfade(y)
    dw = _dfade(z)
    g = (h[0] >> 4, h[1] >> 4, h[2] >> 4, h[3] >> 4, h[4] >> 4, h[5] >> 4, h[6] >> 4, h[7] >> 4)
    n1, g1x, g1y, g1z = _cell_gradient(h, _corner_values(h, x, y, z), u, v, w, du, dv, dw)
    n2, g2x, g2y, g2z = _cell_gradient(g, _corner_values(g, x, y, z), u, v, w, du, dv, dw)
    return n1, g1x, g1y, g1z, n2, g2x, g2y, g2z


@nb.njit(inline="always", cache=True)
def noise3_periodic(p, x, y, z, px, py):
    """Improved noise with integer periods ``px`` along x and ``py`` along y (both <= 256)."""
    ix, x, u = _cell(x)
    iy, y, v = _cell(y)
    iz, z, w = _cell(z)
    ix %= px
    iy %= py
    h = _hashes(p, ix & 255, ((ix + 1) % px) & 255, iy & 255, ((iy + 1) % py) & 255, iz & 255)
    return _trilerp(u, v, w, _corner_values(h, x, y, z))


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
