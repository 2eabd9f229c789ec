"""The noise family on exact Perlin: fBm, turbulence, ridged multifractal, marble,
tileable noise, domain warping, curl noise, and Perlin's bias and gain.

Every function takes coordinates like :func:`procgen.noise.perlin` (scalars or arrays,
broadcast together; omitted ``y``/``z`` are 0), keyword-only options, and ``seed``
(None: Perlin's permutation; an integer: a reproducible permutation). ``t`` adds time
as one more dimension: a 1-D or 2-D field is animated by the next free axis, a 3-D
field by 4-D gradient noise.

One octave of fBm is Perlin bit for bit:

>>> import numpy as np
>>> from procgen.noise import perlin
>>> x = np.linspace(0, 3, 7)
>>> bool(np.all(fbm(x, 0.5, 0.25, octaves=1) == perlin(x, 0.5, 0.25)))
True

References
----------
K. Perlin, "An image synthesizer", SIGGRAPH 1985. doi:10.1145/325165.325247
D. S. Ebert, F. K. Musgrave, D. Peachey, K. Perlin, S. Worley, *Texturing and Modeling:
A Procedural Approach*, 3rd ed., Morgan Kaufmann 2003 (fBm, turbulence, ridged multifractal).
R. Bridson, J. Hourihan, M. Nordenstam, "Curl-noise for procedural fluid flow",
ACM TOG 26(3), 2007. doi:10.1145/1276377.1276435
"""

from __future__ import annotations

import numpy as np

from core.validate import check_finite, check_int, check_range
from procgen.noise import _kernels as K
from procgen.noise.perlin import perm_table

__all__ = [
    "fbm",
    "turbulence",
    "ridged",
    "marble",
    "tileable",
    "warp",
    "curl",
    "bias",
    "gain",
]


def _coords(x, y, z, t):
    """Broadcast coordinates; return flat float64 arrays (x, y, z, w), shape, 4-D flag."""
    given = [np.asarray(x, dtype=np.float64)]
    for c in (y, z):
        if c is not None:
            given.append(np.asarray(c, dtype=np.float64))
    if y is None and z is not None:
        given.insert(1, np.zeros((), np.float64))
    if t is not None:
        given.append(np.asarray(t, dtype=np.float64))
    four = len(given) == 4
    while len(given) < 4:
        given.append(np.zeros((), np.float64))
    arrs = np.broadcast_arrays(*given)
    shape = arrs[0].shape
    flat = [np.ascontiguousarray(a, dtype=np.float64).ravel() for a in arrs]
    return flat, shape, four


def _finish(out, bad, shape):
    if bad:
        raise ValueError("x, y, z, t: expected finite coordinates, got NaN or infinite")
    if shape == ():
        return float(out[0])
    return out.reshape(shape)


def _run(x, y, z, t, seed, octaves, lacunarity, gain_, mode, h=1.0, offset=1.0, rgain=2.0):
    octaves = check_int(octaves, "octaves", 1, 64)
    lac = check_range(lacunarity, "lacunarity", 1.0, None, lo_open=True)
    g = check_finite(gain_, "gain")
    table = perm_table(seed)
    (fx, fy, fz, fw), shape, four = _coords(x, y, z, t)
    out = np.empty(fx.shape[0], dtype=np.float64)
    h_exp = lac ** (-h)
    bad = K.octaves_many(table, fx, fy, fz, fw, four, octaves, lac, g, mode, h_exp,
                         float(offset), float(rgain), out)
    return _finish(out, bad, shape)


def fbm(x, y=None, z=None, *, octaves: int = 5, lacunarity: float = 2.0, gain: float = 0.5,
        t=None, seed: int | None = None):
    """Fractional Brownian motion: ``sum_k gain**k * perlin(lacunarity**k * p)``.

    Parameters
    ----------
    x, y, z : float or array_like
        Coordinates, broadcast together (omitted ``y``/``z`` are 0).
    octaves : int
        Number of octaves, 1 to 64; ``octaves=1`` is :func:`perlin` exactly.
    lacunarity : float
        Frequency ratio between octaves (> 1).
    gain : float
        Amplitude ratio between octaves (0.5 gives a 1/f spectrum).
    t : float or array_like, optional
        Time, an extra dimension that animates the field.
    seed : int or None
        Permutation table (None: Perlin's).

    Returns
    -------
    float or ndarray of float64
        Not normalized: the range grows to about ``±sum_k gain**k``.

    Examples
    --------
    >>> v = fbm(np.array([0.3, 1.7]), 2.2, octaves=5, seed=3)
    >>> v.shape
    (2,)
    """
    return _run(x, y, z, t, seed, octaves, lacunarity, gain, 0)


def turbulence(x, y=None, z=None, *, octaves: int = 5, lacunarity: float = 2.0,
               gain: float = 0.5, t=None, seed: int | None = None):
    """Perlin's turbulence: ``sum_k gain**k * |perlin(lacunarity**k * p)|`` (>= 0).

    With the defaults this is ``sum |noise(2**k p)| / 2**k``, the creases of which make
    marble veins and flames. Options as in :func:`fbm`.

    Examples
    --------
    >>> float(turbulence(0.3, 0.6, 0.9, octaves=4)) >= 0.0
    True
    """
    return _run(x, y, z, t, seed, octaves, lacunarity, gain, 1)


def ridged(x, y=None, z=None, *, octaves: int = 6, lacunarity: float = 2.0, h: float = 1.0,
           offset: float = 1.0, gain: float = 2.0, t=None, seed: int | None = None):
    """Musgrave's ridged multifractal (mountain ridges).

    Each octave's signal is ``(offset - |noise|)**2`` weighted by the previous octave's
    signal times ``gain`` (clamped to [0, 1]) and scaled by ``lacunarity**(-k h)``.

    Parameters
    ----------
    h : float
        Fractal increment (roughness exponent); larger is smoother.
    offset, gain : float
        Musgrave's ridge offset (1.0) and weighting gain (2.0).

    Examples
    --------
    >>> float(ridged(0.0, 0.0, 0.0, octaves=1))  # noise is 0 on the lattice: a ridge top
    1.0
    """
    return _run(x, y, z, t, seed, octaves, lacunarity, 1.0, 2,
                h=check_finite(h, "h"), offset=check_finite(offset, "offset"),
                rgain=check_finite(gain, "gain"))


def marble(x, y=None, z=None, *, frequency: float = 1.0, strength: float = 5.0,
           octaves: int = 5, t=None, seed: int | None = None):
    """Perlin's marble: ``sin(frequency * x + strength * turbulence(p))``, in [-1, 1].

    Examples
    --------
    >>> float(marble(0.0, 0.0, 0.0))
    0.0
    """
    f = check_finite(frequency, "frequency")
    a = check_finite(strength, "strength")
    turb = turbulence(x, y, z, octaves=octaves, t=t, seed=seed)
    xs = np.asarray(x, dtype=np.float64)
    out = np.sin(f * xs + a * np.asarray(turb))
    return float(out) if np.ndim(out) == 0 else out


def tileable(u, v, *, frequency: int = 4, octaves: int = 4, lacunarity: int = 2,
             gain: float = 0.5, t=None, seed: int | None = None):
    """fBm over the unit square that tiles seamlessly: ``f(u + 1, v) == f(u, v + 1) == f(u, v)``.

    The lattice of octave ``k`` is wrapped with period ``frequency * lacunarity**k``
    (an integer <= 256), so the tiling is exact, not blended.

    Parameters
    ----------
    u, v : array_like
        Coordinates; the pattern repeats with period 1 in both.
    frequency : int
        Lattice cells across the square in the first octave.
    lacunarity : int
        Integer frequency ratio between octaves.
    t : float or array_like, optional
        Time (a third, non-periodic dimension) to animate the tile.

    Examples
    --------
    >>> a = tileable(np.array([0.1, 1.1]), 0.3, seed=1)
    >>> bool(abs(a[0] - a[1]) < 1e-12)
    True
    """
    octaves = check_int(octaves, "octaves", 1, 64)
    frequency = check_int(frequency, "frequency")
    lacunarity = check_int(lacunarity, "lacunarity")
    top = frequency * lacunarity ** (octaves - 1)
    if top > 256:
        raise ValueError(f"octaves: frequency * lacunarity**(octaves-1) must be <= 256, got {top}")
    g = check_finite(gain, "gain")
    (fu, fv, fz, _), shape, _ = _coords(u, v, t if t is not None else None, None)
    if not (np.all(np.isfinite(fu)) and np.all(np.isfinite(fv)) and np.all(np.isfinite(fz))):
        raise ValueError("u, v, t: expected finite coordinates, got NaN or infinite")
    out = np.empty(fu.shape[0], dtype=np.float64)
    K.tileable_many(perm_table(seed), fu, fv, fz, int(frequency), octaves, int(lacunarity), g, out)
    return _finish(out, 0, shape)


# Offsets that decorrelate the components of vector-valued noise (Quilez's choice).
_OFFSETS = np.array([[0.0, 0.0, 0.0], [5.2, 1.3, 2.8], [1.7, 9.2, 4.6], [8.3, 2.8, 7.1]])


def warp(x, y=None, z=None, *, amount: float = 1.0, octaves: int = 5, lacunarity: float = 2.0,
         gain: float = 0.5, t=None, seed: int | None = None):
    """Domain-warped fBm: ``fbm(p + amount * (fbm(p + o1), fbm(p + o2), fbm(p + o3)))``.

    ``amount=0`` is plain :func:`fbm`. Options as in :func:`fbm`.

    Examples
    --------
    >>> float(warp(0.3, 0.4, 0.5, amount=0.0)) == float(fbm(0.3, 0.4, 0.5))
    True
    """
    a = check_finite(amount, "amount")
    kw = dict(octaves=octaves, lacunarity=lacunarity, gain=gain, t=t, seed=seed)
    xs = np.asarray(x, dtype=np.float64)
    ys = np.zeros((), np.float64) if y is None else np.asarray(y, dtype=np.float64)
    zs = np.zeros((), np.float64) if z is None else np.asarray(z, dtype=np.float64)
    xs, ys, zs = np.broadcast_arrays(xs, ys, zs)
    if a == 0.0:
        return fbm(xs, ys, zs, **kw)
    o = _OFFSETS
    qx = fbm(xs + o[1, 0], ys + o[1, 1], zs + o[1, 2], **kw)
    qy = fbm(xs + o[2, 0], ys + o[2, 1], zs + o[2, 2], **kw)
    qz = fbm(xs + o[3, 0], ys + o[3, 1], zs + o[3, 2], **kw) if z is not None else 0.0
    return fbm(xs + a * qx, ys + a * qy, zs + a * qz, **kw)


def curl(x, y, z=None, *, octaves: int = 1, lacunarity: float = 2.0, gain: float = 0.5,
         t=None, seed: int | None = None) -> np.ndarray:
    """Curl noise: a divergence-free velocity field for particles (Bridson et al. 2007).

    3-D (``z`` given): the curl of the potential ``psi = (N(p + o1), N(p + o2), N(p + o3))``
    with ``N`` the fBm of :func:`fbm`; 2-D (``z`` None): ``(dpsi/dy, -dpsi/dx)`` of one
    fBm. Derivatives are analytic, so the divergence is zero up to rounding.

    Parameters
    ----------
    x, y, z : array_like
        Coordinates, broadcast together.
    t : float or array_like, optional
        Time. In 2-D it is the third noise dimension; in 3-D the three potential
        components drift along different directions with ``t`` (each is still a curl,
        so the field stays divergence-free).

    Returns
    -------
    ndarray of float64, shape ``broadcast + (3,)`` (3-D) or ``broadcast + (2,)`` (2-D)

    Examples
    --------
    >>> curl(np.array([0.1, 0.2]), 0.3, 0.4).shape
    (2, 3)
    """
    octaves = check_int(octaves, "octaves", 1, 64)
    lac = check_range(lacunarity, "lacunarity", 1.0, None, lo_open=True)
    g = check_finite(gain, "gain")
    table = perm_table(seed)
    xs = np.asarray(x, dtype=np.float64)
    ys = np.asarray(y, dtype=np.float64)
    zs = np.zeros((), np.float64) if z is None else np.asarray(z, dtype=np.float64)
    ts = np.zeros((), np.float64) if t is None else np.asarray(t, dtype=np.float64)
    bx, by, bz, bt = np.broadcast_arrays(xs, ys, zs, ts)
    shape = bx.shape
    fx, fy, fz, ft = (np.ascontiguousarray(a, dtype=np.float64).ravel() for a in (bx, by, bz, bt))
    if not all(np.all(np.isfinite(a)) for a in (fx, fy, fz, ft)):
        raise ValueError("x, y, z, t: expected finite coordinates, got NaN or infinite")
    n = fx.shape[0]

    def potential(k, drift):
        o = _OFFSETS[k]
        out = np.empty((n, 4), dtype=np.float64)
        K.fbm_grad_many(table, fx + o[0] + drift[0] * ft, fy + o[1] + drift[1] * ft,
                        fz + o[2] + drift[2] * ft, octaves, lac, g, out)
        return out

    if z is None:
        # the third noise axis is time
        ps = potential(0, (0.0, 0.0, 1.0))
        vel = np.stack([ps[:, 2], -ps[:, 1]], axis=1)
        return vel.reshape(shape + (2,))
    p1 = potential(1, (1.0, 0.0, 0.0))
    p2 = potential(2, (0.0, 1.0, 0.0))
    p3 = potential(3, (0.0, 0.0, 1.0))
    vel = np.stack([p3[:, 2] - p2[:, 3], p1[:, 3] - p3[:, 1], p2[:, 1] - p1[:, 2]], axis=1)
    return vel.reshape(shape + (3,))


def bias(t, b: float):
    """Perlin's bias: ``t**(log b / log 0.5)``; maps [0, 1] onto itself with ``bias(0.5) == b``.

    >>> float(bias(0.5, 0.8))
    0.8
    """
    b = check_range(b, "b", 0.0, 1.0, lo_open=True, hi_open=True)
    ts = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    out = np.power(ts, np.log(b) / np.log(0.5))
    return float(out) if out.ndim == 0 else out


def gain(t, g: float):
    """Perlin's gain through (0.5, 0.5): ``g > 0.5`` steepens the middle (an S-curve),
    ``g < 0.5`` flattens it; ``g = 0.5`` is the identity.

    >>> float(gain(0.5, 0.3)), float(gain(0.25, 0.5))
    (0.5, 0.25)
    """
    g = check_range(g, "g", 0.0, 1.0, lo_open=True, hi_open=True)
    ts = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    e = np.log(1.0 - g) / np.log(0.5)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo = 0.5 * np.power(2.0 * ts, e)
        hi = 1.0 - 0.5 * np.power(np.maximum(2.0 - 2.0 * ts, 0.0), e)
    out = np.where(ts < 0.5, lo, hi)
    return float(out) if out.ndim == 0 else out
