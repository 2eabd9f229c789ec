"""Random midpoint displacement: 1-D profiles and 2-D diamond-square heightfields.

Diamond-square follows Saupe's ``MidPointFM2D`` (The Science of Fractal Images, 1988):
on a ``(2**n + 1)**2`` grid, each stage halves the spacing, fills the centres of the
squares (diamond step) and then the edge midpoints (square step) with the mean of
their neighbours plus Gaussian noise whose deviation shrinks by ``2**(-H/2)`` per
half-step; the optional addition step adds noise to every existing point as well.
The increments of the result scale as ``|h|**H``: the variogram has slope ``2 H`` and
the surface a box-counting dimension ``3 - H``.

Each stage draws its normals from ``rng`` in one call and fills the grid in one
parallel compiled pass.

References
----------
A. Fournier, D. Fussell, L. Carpenter, "Computer rendering of stochastic models",
CACM 25(6), 1982. doi:10.1145/358523.358553
D. Saupe, "Algorithms for random fractals", in H.-O. Peitgen, D. Saupe (eds.),
*The Science of Fractal Images*, Springer 1988, ch. 2. doi:10.1007/978-1-4612-3784-6_2
"""

from __future__ import annotations

import numba as nb
import numpy as np

from core.validate import check_array, check_int, check_positive, check_range, check_rng

__all__ = ["midpoint_displacement", "diamond_square", "refine_heightfield"]

_MAX_N = 14


def _check_hurst(hurst) -> float:
    return check_range(hurst, "hurst", 0.0, 1.0, lo_open=True, hi_open=True)


def midpoint_displacement(n: int, *, decay: float = 0.5, sigma: float = 1.0,
                          endpoints=(0.0, 0.0), rng: np.random.Generator) -> np.ndarray:
    """1-D random midpoint displacement on ``2**n + 1`` samples.

    At level ``k`` (``k = 0`` first) each new midpoint is the mean of its two
    neighbours plus ``sigma * decay**k`` times a standard normal; ``decay = 2**-H``
    gives a profile of Hurst exponent ``H``.

    Parameters
    ----------
    n : int
        Number of levels (1 to 14).
    decay : float
        Displacement decay factor per level, ``0 < decay < 1``.
    sigma : float
        Deviation of the first displacement.
    endpoints : (2,) float
        Heights at both ends.
    rng : numpy.random.Generator

    Returns
    -------
    (2**n + 1,) float64

    Examples
    --------
    >>> h = midpoint_displacement(4, decay=0.6, rng=np.random.default_rng(0))
    >>> h.shape, float(h[0]), float(h[-1])
    ((17,), 0.0, 0.0)
    """
    n = check_int(n, "n", 1, _MAX_N)
    f = check_range(decay, "decay", 0.0, 1.0, lo_open=True, hi_open=True)
    s = check_positive(sigma, "sigma", allow_zero=True)
    ends = check_array(endpoints, "endpoints", shape=(2,))
    rng = check_rng(rng)
    size = 2 ** n
    out = np.empty(size + 1)
    out[0], out[-1] = ends
    step = size
    delta = s
    while step > 1:
        half = step // 2
        mids = 0.5 * (out[0:-1:step] + out[step::step])
        out[half::step] = mids + delta * rng.standard_normal(mids.shape[0])
        delta *= f
        step = half
    return out


@nb.njit(parallel=True, cache=True)
def _stage(X, D, delta_c, delta_e, noise):
    """One diamond-square stage on ``X`` (in place): centres, then edge midpoints.

    ``noise`` holds the standard normals: the centres' (``m_r * m_c``), then those of
    the midpoints on lattice rows (``(m_r + 1) * m_c``), then on lattice columns
    (``m_r * (m_c + 1)``).
    """
    d = D // 2
    m_r = (X.shape[0] - 1) // D
    m_c = (X.shape[1] - 1) // D
    for i in nb.prange(m_r):
        r0 = i * D
        for j in range(m_c):
            c0 = j * D
            X[r0 + d, c0 + d] = 0.25 * (X[r0, c0] + X[r0, c0 + D] + X[r0 + D, c0]
                                        + X[r0 + D, c0 + D]) + delta_c * noise[i * m_c + j]
    off_e = m_r * m_c
    off_f = off_e + (m_r + 1) * m_c
    for i in nb.prange(m_r + 1):
        r = i * D
        for j in range(m_c):
            c = j * D + d
            s = X[r, c - d] + X[r, c + d]
            k = 2.0
            if i > 0:
                s += X[r - d, c]
                k += 1.0
            if i < m_r:
                s += X[r + d, c]
                k += 1.0
            X[r, c] = s / k + delta_e * noise[off_e + i * m_c + j]
    for i in nb.prange(m_r):
        r = i * D + d
        for j in range(m_c + 1):
            c = j * D
            s = X[r - d, c] + X[r + d, c]
            k = 2.0
            if j > 0:
                s += X[r, c - d]
                k += 1.0
            if j < m_c:
                s += X[r, c + d]
                k += 1.0
            X[r, c] = s / k + delta_e * noise[off_f + i * (m_c + 1) + j]


def _stages(X: np.ndarray, D: int, delta: float, hurst: float, addition: bool,
            rng: np.random.Generator) -> np.ndarray:
    """Run diamond-square stages on ``X`` (shape ``(a D + 1, b D + 1)``) down to spacing 1.

    Points on the ``D`` lattice are kept (unless ``addition``); ``delta`` is the
    deviation before the first stage's diamond step. The normals of each stage are
    drawn from ``rng`` in one call, so the result depends only on the seed.
    """
    r = 0.5 ** (0.5 * hurst)
    normals = _Normals(rng)
    while D > 1:
        d = D // 2
        m_r = (X.shape[0] - 1) // D
        m_c = (X.shape[1] - 1) // D
        count = m_r * m_c + (m_r + 1) * m_c + m_r * (m_c + 1)
        delta_c = delta * r
        delta_e = delta_c * r
        noise = normals(count)
        if addition:
            # Saupe's order: lattice points get noise after the diamond step, and every
            # point of the finer lattice after the square step.
            G = X[::D, ::D]
            _stage_diamond_only(X, D, delta_c, noise)
            G += delta_c * rng.standard_normal(G.shape)
            _stage_square_only(X, D, delta_e, noise)
            X[::d, ::d] += delta_e * rng.standard_normal(X[::d, ::d].shape)
        else:
            _stage(X, D, delta_c, delta_e, noise)
        delta = delta_e
        D = d
    normals.close()
    return X


class _Normals:
    """Standard normals for the stages, drawn in two halves on two threads when large.

    The halves come from two child generators spawned from ``rng`` once, so the values
    depend only on the seed (not on the number of cores).
    """

    _SPLIT = 1 << 20

    def __init__(self, rng: np.random.Generator):
        self.rng = rng
        self.kids = None
        self.pool = None

    def __call__(self, count: int) -> np.ndarray:
        if count < self._SPLIT:
            return self.rng.standard_normal(count)
        if self.kids is None:
            from concurrent.futures import ThreadPoolExecutor

            self.kids = self.rng.spawn(2)
            self.pool = ThreadPoolExecutor(2)
        out = np.empty(count)
        h = count // 2
        jobs = [self.pool.submit(k.standard_normal, out=part)
                for k, part in ((self.kids[0], out[:h]), (self.kids[1], out[h:]))]
        for j in jobs:
            j.result()
        return out

    def close(self):
        if self.pool is not None:
            self.pool.shutdown()


def _stage_diamond_only(X, D, delta_c, noise):
    d = D // 2
    G = X[::D, ::D]
    m_r, m_c = G.shape[0] - 1, G.shape[1] - 1
    C = 0.25 * (G[:-1, :-1] + G[:-1, 1:] + G[1:, :-1] + G[1:, 1:])
    C += delta_c * noise[: m_r * m_c].reshape(m_r, m_c)
    X[d::D, d::D] = C


def _stage_square_only(X, D, delta_e, noise):
    d = D // 2
    G = X[::D, ::D]
    C = X[d::D, d::D]
    m_r, m_c = C.shape
    off_e = m_r * m_c
    off_f = off_e + (m_r + 1) * m_c
    E = G[:, :-1] + G[:, 1:]
    cnt = np.full((m_r + 1, 1), 4.0)
    cnt[0] = cnt[-1] = 3.0
    E[:-1] += C
    E[1:] += C
    E /= cnt
    E += delta_e * noise[off_e:off_f].reshape(m_r + 1, m_c)
    F = G[:-1, :] + G[1:, :]
    cnt = np.full((1, m_c + 1), 4.0)
    cnt[0, 0] = cnt[0, -1] = 3.0
    F[:, :-1] += C
    F[:, 1:] += C
    F /= cnt
    F += delta_e * noise[off_f:].reshape(m_r, m_c + 1)
    X[::D, d::D] = E
    X[d::D, ::D] = F


def diamond_square(n: int, *, hurst: float, rng: np.random.Generator, sigma: float = 1.0,
                   addition: bool = False, control=None) -> np.ndarray:
    """Fractional Brownian surface on a ``(2**n + 1, 2**n + 1)`` grid (Saupe's MidPointFM2D).

    Parameters
    ----------
    n : int
        Size exponent, 1 to 14: the grid has ``2**n + 1`` points a side.
    hurst : float
        Hurst exponent ``H`` in (0, 1); rougher when small. Dimension ``3 - H``.
    rng : numpy.random.Generator
    sigma : float
        Deviation of the initial corners (the overall height scale).
    addition : bool
        Saupe's addition step (noise added to all points at every stage), which
        removes most of the creases along the coarse grid lines.
    control : (2**k + 1, 2**k + 1) float, optional
        A coarse heightfield (``k <= n``) kept as the control surface: the result
        passes through it exactly (unless ``addition``) and adds finer detail, see
        :func:`refine_heightfield`.

    Returns
    -------
    (2**n + 1, 2**n + 1) float64

    Examples
    --------
    >>> z = diamond_square(5, hurst=0.8, rng=np.random.default_rng(1))
    >>> z.shape
    (33, 33)
    """
    n = check_int(n, "n", 1, _MAX_N)
    h = _check_hurst(hurst)
    rng = check_rng(rng)
    s = check_positive(sigma, "sigma", allow_zero=True)
    if control is not None:
        c = check_array(control, "control", shape=(None, None))
        k = _grid_exponent(c.shape[0], "control")
        if c.shape[0] != c.shape[1] or k > n:
            raise ValueError(f"control: expected a square (2**k + 1) grid with k <= n = {n}, "
                             f"got shape {c.shape}")
        return refine_heightfield(c, n - k, hurst=h, rng=rng, addition=addition)
    size = 2 ** n
    X = np.empty((size + 1, size + 1))
    X[::size, ::size] = s * rng.standard_normal((2, 2))
    return _stages(X, size, s, h, addition, rng)


def _grid_exponent(length: int, name: str) -> int:
    m = length - 1
    if m < 1 or m & (m - 1):
        raise ValueError(f"{name}: expected a grid of 2**k + 1 points a side, got {length}")
    return m.bit_length() - 1


def refine_heightfield(heights, levels: int, *, hurst: float, rng: np.random.Generator,
                       sigma: float | None = None, addition: bool = False) -> np.ndarray:
    """Amplify a coarse heightfield with constrained diamond-square detail.

    The coarse samples become every ``2**levels``-th sample of the result, which
    passes through them exactly (unless ``addition``); the stages in between add
    fractal detail with Hurst exponent ``hurst``. This is the way to amplify a
    reconstructed terrain: its heightfield is the control surface.

    Parameters
    ----------
    heights : (r, c) float64
        Coarse heights, r, c >= 2, finite.
    levels : int
        Number of halvings of the spacing (0 to 14).
    hurst : float
        Hurst exponent in (0, 1).
    rng : numpy.random.Generator
    sigma : float, optional
        Deviation of the first displacement. By default it continues the roughness of
        the control surface: ``sqrt(mean(neighbour differences**2) / 2)``.

    Returns
    -------
    ((r - 1) * 2**levels + 1, (c - 1) * 2**levels + 1) float64

    Examples
    --------
    >>> coarse = np.array([[0.0, 1.0], [1.0, 2.0]])
    >>> fine = refine_heightfield(coarse, 3, hurst=0.7, rng=np.random.default_rng(0))
    >>> fine.shape, bool(np.array_equal(fine[::8, ::8], coarse))
    ((9, 9), True)
    """
    c = check_array(heights, "heights", shape=(None, None))
    if c.shape[0] < 2 or c.shape[1] < 2:
        raise ValueError(f"heights: expected at least a 2 x 2 grid, got shape {c.shape}")
    L = check_int(levels, "levels", lo=0)
    h = _check_hurst(hurst)
    rng = check_rng(rng)
    if (c.shape[0] - 1) * 2 ** L + 1 > 2 ** _MAX_N + 1 or (c.shape[1] - 1) * 2 ** L + 1 > \
            2 ** _MAX_N + 1:
        raise ValueError(f"levels: the refined grid would exceed {2 ** _MAX_N + 1} points a side")
    if sigma is None:
        diffs = np.concatenate([np.diff(c, axis=0).ravel(), np.diff(c, axis=1).ravel()])
        s = float(np.sqrt(np.mean(diffs ** 2) / 2.0))
    else:
        s = check_positive(sigma, "sigma", allow_zero=True)
    D = 2 ** L
    X = np.empty(((c.shape[0] - 1) * D + 1, (c.shape[1] - 1) * D + 1))
    X[::D, ::D] = c
    return _stages(X, D, s, h, addition, rng)
