"""Ken Perlin's improved noise (2002), exact and vectorized.

With the reference permutation (``seed=None``) this reproduces Perlin's Java
reference implementation bit for bit (up to floating-point order, < 1e-15):

>>> round(float(perlin(3.14, 42, 7)), 12)
0.136919958784
>>> float(perlin(1.0, 2.0, 3.0))
0.0

1-D and 2-D noise are the 3-D function on the planes ``z = 0`` (and ``y = 0``), so
they are zero at integer lattice points too. Other seeds permute the table
reproducibly (``numpy.random.default_rng(seed).permutation(256)``).

The scalar kernel :func:`noise3` is a numba function that other compiled kernels
(fBm, turbulence, curl noise) call inline; :func:`perm_table` gives its table.

References
----------
K. Perlin, "Improving noise", ACM TOG 21(3), SIGGRAPH 2002. doi:10.1145/566654.566636
"""

from __future__ import annotations

import functools

import numba as nb
import numpy as np

__all__ = ["perlin", "perm_table", "noise3", "REFERENCE_PERMUTATION"]

REFERENCE_PERMUTATION = np.array([
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30,
    69, 142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94,
    252, 219, 203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171,
    168, 68, 175, 74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60,
    211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216,
    80, 73, 209, 76, 132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100,
    109, 198, 173, 186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82,
    85, 212, 207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248,
    152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108,
    110, 79, 113, 224, 232, 178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210,
    144, 12, 191, 179, 162, 241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199,
    106, 157, 184, 84, 204, 176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114,
    67, 29, 24, 72, 243, 141, 128, 195, 78, 66, 215, 61, 156, 180,
], dtype=np.int32)


@functools.lru_cache(maxsize=64)
def _table(seed: int | None) -> np.ndarray:
    if seed is None:
        perm = REFERENCE_PERMUTATION
    else:
        perm = np.random.default_rng(seed).permutation(256).astype(np.int64)
    out = np.concatenate([perm, perm]).astype(np.int64)
    out.setflags(write=False)
    return out


def perm_table(seed: int | None = None) -> np.ndarray:
    """The doubled permutation table ``(512,) int64`` for ``seed`` (None: Perlin's)."""
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
        raise ValueError(f"seed: expected an integer or None, got {seed!r}")
    return _table(None if seed is None else int(seed))


@nb.njit(inline="always", cache=True)
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@nb.njit(inline="always", cache=True)
def _lerp(t, a, b):
    return a + t * (b - a)


def _gradient_table() -> np.ndarray:
    """Perlin's 16 gradient vectors: ``grad(h, x, y, z) == G[h & 15] . (x, y, z)`` exactly.

    A table lookup instead of the reference's branches (which mispredict on random
    hashes); the sums are the same two non-zero terms in the same order.
    """
    g = np.zeros((16, 3))
    for h in range(16):
        iu = 0 if h < 8 else 1
        iv = 1 if h < 4 else (0 if h in (12, 14) else 2)
        g[h, iu] += 1.0 if (h & 1) == 0 else -1.0
        g[h, iv] += 1.0 if (h & 2) == 0 else -1.0
    return g


_G = _gradient_table()
_GX = np.ascontiguousarray(_G[:, 0])
_GY = np.ascontiguousarray(_G[:, 1])
_GZ = np.ascontiguousarray(_G[:, 2])


@nb.njit(inline="always", cache=True)
def _grad(h, x, y, z):
    h = h & 15
    return _GX[h] * x + _GY[h] * y + _GZ[h] * z


@nb.njit(inline="always", cache=True)
def _cell(x):
    """Lattice cell of one coordinate: ``(integer part as int64, fraction, fade(fraction))``."""
    f = np.floor(x)
    x -= f
    return np.int64(f), x, _fade(x)


@nb.njit(inline="always", cache=True)
def _hashes(p, X, X1, Y, Y1, Z):
    """Hashes of the 8 cell corners in the order (000, 100, 010, 110, 001, 101, 011, 111).

    ``X1``/``Y1`` are the next lattice indices (``X + 1``, or wrapped for periodic noise);
    all indices are already reduced to [0, 255]. They index as unsigned integers: numba
    checks every signed index for a negative wrap-around, which cost 17 % of fBm's time."""
    u = np.uint64
    pX, pX1, Y, Y1, Z = u(p[u(X)]), u(p[u(X1)]), u(Y), u(Y1), u(Z)
    pA, pB, pA1, pB1 = u(p[pX + Y]), u(p[pX1 + Y]), u(p[pX + Y1]), u(p[pX1 + Y1])
    Z1 = Z + u(1)
    return (p[pA + Z], p[pB + Z], p[pA1 + Z], p[pB1 + Z],
            p[pA + Z1], p[pB + Z1], p[pA1 + Z1], p[pB1 + Z1])


@nb.njit(inline="always", cache=True)
def _corner_values(h, x, y, z):
    """Gradient dot offset at the 8 corners (hashes ``h`` from :func:`_hashes`)."""
    x1 = x - 1.0
    y1 = y - 1.0
    z1 = z - 1.0
    return (_grad(h[0], x, y, z), _grad(h[1], x1, y, z), _grad(h[2], x, y1, z),
            _grad(h[3], x1, y1, z), _grad(h[4], x, y, z1), _grad(h[5], x1, y, z1),
            _grad(h[6], x, y1, z1), _grad(h[7], x1, y1, z1))


@nb.njit(inline="always", cache=True)
def _trilerp(u, v, w, c):
    return _lerp(w, _lerp(v, _lerp(u, c[0], c[1]), _lerp(u, c[2], c[3])),
                 _lerp(v, _lerp(u, c[4], c[5]), _lerp(u, c[6], c[7])))


@nb.njit(inline="always", cache=True)
def noise3(p, x, y, z):
    """Improved noise at one point; ``p`` is a table from :func:`perm_table`."""
    ix, x, u = _cell(x)
    iy, y, v = _cell(y)
    iz, z, w = _cell(z)
    X = ix & 255
    Y = iy & 255
    h = _hashes(p, X, X + 1, Y, Y + 1, iz & 255)
    return _trilerp(u, v, w, _corner_values(h, x, y, z))


@nb.njit(parallel=True, cache=True)
def _perlin_many(p, x, y, z, out):
    bad = 0
    for i in nb.prange(x.shape[0]):
        xi = x[i]
        yi = y[i]
        zi = z[i]
        if np.isfinite(xi) and np.isfinite(yi) and np.isfinite(zi):
            out[i] = noise3(p, xi, yi, zi)
        else:
            out[i] = np.nan
            bad += 1
    return bad


def perlin(x, y=None, z=None, *, seed: int | None = None):
    """Improved Perlin noise at points, 1-D to 3-D, broadcast over array inputs.

    Parameters
    ----------
    x, y, z : float or array_like
        Coordinates; omitted ``y``/``z`` are 0 (1-D and 2-D noise are slices of 3-D).
    seed : int or None
        None uses Perlin's reference permutation; an integer permutes it reproducibly.

    Returns
    -------
    float or ndarray of float64
        Values in about [-1, 1], with the broadcast shape of the inputs.

    Examples
    --------
    >>> import numpy as np
    >>> perlin(np.arange(3.0)).tolist()
    [0.0, 0.0, 0.0]
    """
    table = perm_table(seed)
    xs = np.asarray(x, dtype=np.float64)
    ys = np.zeros((), np.float64) if y is None else np.asarray(y, dtype=np.float64)
    zs = np.zeros((), np.float64) if z is None else np.asarray(z, dtype=np.float64)
    bx, by, bz = np.broadcast_arrays(xs, ys, zs)
    shape = bx.shape
    fx = np.ascontiguousarray(bx).ravel()
    fy = np.ascontiguousarray(by).ravel()
    fz = np.ascontiguousarray(bz).ravel()
    out = np.empty(fx.shape[0], dtype=np.float64)
    if _perlin_many(table, fx, fy, fz, out):
        raise ValueError("x, y, z: expected finite coordinates, got NaN or infinite")
    if shape == ():
        return float(out[0])
    return out.reshape(shape)
