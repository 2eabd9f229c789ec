"""Deterministic fractals: Koch curve and snowflake, Sierpinski triangle, iterated
function systems by the chaos game (Barnsley's fern), Mandelbrot and Julia sets by
escape time.

>>> koch_curve(2).shape
(17, 2)
>>> sierpinski_triangle(3).shape
(27, 3, 2)

References
----------
M. F. Barnsley, *Fractals Everywhere*, Academic Press 1988 (IFS, the fern).
H.-O. Peitgen, P. H. Richter, *The Beauty of Fractals*, Springer 1986 (escape time).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from core.validate import check_array, check_int, check_positive, check_rng

__all__ = [
    "koch_curve",
    "koch_snowflake",
    "sierpinski_triangle",
    "chaos_game",
    "barnsley_fern",
    "BARNSLEY_FERN",
    "mandelbrot",
    "julia",
    "colorize_escape",
]


def koch_curve(level: int, *, start=(0.0, 0.0), end=(1.0, 0.0)) -> np.ndarray:
    """Koch curve polyline: ``4**level + 1`` vertices from ``start`` to ``end``.

    Each segment is replaced by four of a third of its length, the middle two forming
    an equilateral bump to the left of the direction of travel. Length ``(4/3)**level``
    times the chord; similarity dimension ``log 4 / log 3 = 1.2619``.

    Returns
    -------
    (4**level + 1, 2) float64
    """
    level = check_int(level, "level", 0, 12)
    pts = np.array([check_array(start, "start", shape=(2,)), check_array(end, "end", shape=(2,))])
    rot = np.array([[0.5, -np.sqrt(3) / 2], [np.sqrt(3) / 2, 0.5]])  # +60 degrees
    for _ in range(level):
        a = pts[:-1]
        b = pts[1:]
        d = (b - a) / 3.0
        p1 = a + d
        p3 = a + 2.0 * d
        p2 = p1 + d @ rot.T
        new = np.empty((4 * len(a) + 1, 2))
        new[0:-1:4] = a
        new[1::4] = p1
        new[2::4] = p2
        new[3::4] = p3
        new[-1] = pts[-1]
        pts = new
    return pts


def koch_snowflake(level: int, *, radius: float = 1.0) -> np.ndarray:
    """Closed Koch snowflake: ``3 * 4**level + 1`` vertices (the last repeats the first).

    The level-0 triangle is inscribed in a circle of ``radius`` about the origin and
    the bumps point outwards; the area tends to ``8/5`` of the triangle's.

    Returns
    -------
    (3 * 4**level + 1, 2) float64
    """
    r = check_positive(radius, "radius")
    ang = np.pi / 2 - 2 * np.pi * np.arange(3) / 3  # clockwise: bumps to the left = outwards
    corners = r * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    sides = [koch_curve(level, start=corners[i], end=corners[(i + 1) % 3])[:-1] for i in range(3)]
    out = np.vstack(sides)
    return np.vstack([out, out[:1]])


_UNIT_TRIANGLE = ((0.0, 0.0), (1.0, 0.0), (0.5, 0.8660254037844386))


def sierpinski_triangle(level: int, *, corners=_UNIT_TRIANGLE) -> np.ndarray:
    """The ``3**level`` filled triangles of the Sierpinski triangle at ``level``.

    Returns
    -------
    (3**level, 3, 2) float64
        Triangle corners; total area ``(3/4)**level`` of the initial one; similarity
        dimension ``log 3 / log 2 = 1.585``.
    """
    level = check_int(level, "level", 0, 12)
    tri = check_array(corners, "corners", shape=(3, 2))[None]
    for _ in range(level):
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        tri = np.stack([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                        np.stack([ca, bc, c], 1)], axis=1).reshape(-1, 3, 2)
    return tri


@nb.njit(cache=True)
def _chaos(A, b, choice, x0, burn_in, out):
    x = x0[0]
    y = x0[1]
    n = out.shape[0]
    for i in range(n + burn_in):
        k = choice[i]
        nx = A[k, 0, 0] * x + A[k, 0, 1] * y + b[k, 0]
        y = A[k, 1, 0] * x + A[k, 1, 1] * y + b[k, 1]
        x = nx
        if i >= burn_in:
            out[i - burn_in, 0] = x
            out[i - burn_in, 1] = y


def chaos_game(maps, probabilities, n: int, *, rng: np.random.Generator,
               burn_in: int = 20) -> np.ndarray:
    """Points of an IFS attractor by the chaos game (random iteration).

    Parameters
    ----------
    maps : (k, 2, 3) float
        Affine maps ``x -> M[:, :2] @ x + M[:, 2]``, contractive.
    probabilities : (k,) float
        Choice probabilities (normalized here).
    n : int
        Number of points returned (after ``burn_in`` discarded iterations).
    rng : numpy.random.Generator

    Returns
    -------
    (n, 2) float64
    """
    M = check_array(maps, "maps", shape=(None, 2, 3), min_rows=1)
    p = check_array(probabilities, "probabilities", shape=(M.shape[0],))
    if np.any(p < 0) or p.sum() <= 0:
        raise ValueError("probabilities: expected non-negative values with a positive sum")
    n = check_int(n, "n", 1, 10 ** 9)
    check_rng(rng)
    choice = rng.choice(M.shape[0], size=n + burn_in, p=p / p.sum()).astype(np.int64)
    out = np.empty((n, 2))
    _chaos(np.ascontiguousarray(M[:, :, :2]), np.ascontiguousarray(M[:, :, 2]), choice,
           np.zeros(2), int(burn_in), out)
    return out


BARNSLEY_FERN = (
    np.array([[[0.0, 0.0, 0.0], [0.0, 0.16, 0.0]],
              [[0.85, 0.04, 0.0], [-0.04, 0.85, 1.6]],
              [[0.2, -0.26, 0.0], [0.23, 0.22, 1.6]],
              [[-0.15, 0.28, 0.0], [0.26, 0.24, 0.44]]]),
    np.array([0.01, 0.85, 0.07, 0.07]),
)
"""Barnsley's fern: its four affine maps ``(4, 2, 3)`` and their probabilities."""


def barnsley_fern(n: int, *, rng: np.random.Generator) -> np.ndarray:
    """``n`` points of Barnsley's fern (inside x in [-2.182, 2.6558], y in [0, 9.9983]).

    >>> pts = barnsley_fern(1000, rng=np.random.default_rng(0))
    >>> bool(pts[:, 1].min() >= 0 and pts[:, 1].max() < 10)
    True
    """
    maps, probs = BARNSLEY_FERN
    return chaos_game(maps, probs, n, rng=rng)


@nb.njit(parallel=True, cache=True)
def _escape(re0, im0, cre, cim, julia, max_iter, out):
    h, w = out.shape
    for i in nb.prange(h):
        for j in range(w):
            pr = re0[j]
            pi = im0[i]
            if julia:
                zr, zi, cr, ci = pr, pi, cre, cim
            else:
                zr, zi, cr, ci = 0.0, 0.0, pr, pi
            k = 0
            zr2 = zr * zr
            zi2 = zi * zi
            while k < max_iter and zr2 + zi2 <= 256.0:  # bailout 16 for smooth colouring
                zi = 2.0 * zr * zi + ci
                zr = zr2 - zi2 + cr
                zr2 = zr * zr
                zi2 = zi * zi
                k += 1
            if k >= max_iter:
                out[i, j] = np.inf
            else:
                # smooth iteration count (continuous escape time)
                out[i, j] = k + 1.0 - np.log(np.log(np.sqrt(zr2 + zi2))) / np.log(2.0)


def _view(width, height, center, zoom, span):
    w = check_int(width, "width", 1, 20000)
    h = check_int(height, "height", 1, 20000)
    c = check_array(center, "center", shape=(2,))
    z = check_positive(zoom, "zoom")
    half_w = span / z / 2.0
    half_h = half_w * h / w
    re = c[0] + np.linspace(-half_w, half_w, w)
    im = c[1] + np.linspace(half_h, -half_h, h)  # image row 0 at the top
    return re, im, h, w


def mandelbrot(width: int, height: int, *, center=(-0.5, 0.0), zoom: float = 1.0,
               max_iter: int = 256) -> np.ndarray:
    """Escape-time image of the Mandelbrot set ``z -> z**2 + c``, ``z0 = 0``.

    Parameters
    ----------
    width, height : int
        Pixels.
    center : (2,) float
        Complex centre ``(re, im)`` of the view.
    zoom : float
        Magnification; ``zoom = 1`` shows a width of 3 in the complex plane.
    max_iter : int

    Returns
    -------
    (height, width) float64
        Smooth (continuous) escape count; ``inf`` inside the set (no escape within
        ``max_iter``). Row 0 is the top (largest imaginary part).

    Examples
    --------
    >>> img = mandelbrot(5, 3, center=(0.0, 0.0), zoom=3.0)
    >>> bool(np.isinf(img[1, 2]))  # c = 0 is inside
    True
    """
    re, im, _, _ = _view(width, height, center, zoom, 3.0)
    it = check_int(max_iter, "max_iter", 1, 10 ** 7)
    out = np.empty((len(im), len(re)))
    _escape(re, im, 0.0, 0.0, False, it, out)
    return out


def julia(width: int, height: int, *, c=(-0.8, 0.156), center=(0.0, 0.0), zoom: float = 1.0,
          max_iter: int = 256) -> np.ndarray:
    """Escape-time image of the filled Julia set of ``z -> z**2 + c``.

    Same view and output as :func:`mandelbrot` (``zoom = 1`` shows a width of 3);
    ``c = 0`` gives the unit disc.

    >>> img = julia(3, 3, c=(0.0, 0.0), zoom=1.0)
    >>> bool(np.isinf(img[1, 1])), bool(np.isfinite(img[0, 0]))
    (True, True)
    """
    re, im, _, _ = _view(width, height, center, zoom, 3.0)
    cc = check_array(c, "c", shape=(2,))
    it = check_int(max_iter, "max_iter", 1, 10 ** 7)
    out = np.empty((len(im), len(re)))
    _escape(re, im, float(cc[0]), float(cc[1]), True, it, out)
    return out


def colorize_escape(counts, *, cmap: str = "twilight_shifted", cycle: float = 64.0,
                    inside=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Colour an escape-time image: a cyclic colour map of the smooth count.

    Parameters
    ----------
    counts : (h, w) float
        From :func:`mandelbrot` or :func:`julia` (``inf`` inside the set).
    cmap : str
        A matplotlib colour map name.
    cycle : float
        Iterations per turn of the colour map.
    inside : (3,) float
        Colour of the set itself.

    Returns
    -------
    (h, w, 3) uint8
    """
    from matplotlib import colormaps

    cnt = np.asarray(counts, dtype=np.float64)
    if cnt.ndim != 2:
        raise ValueError(f"counts: expected shape (h, w), got {cnt.shape}")
    if cmap not in colormaps:
        raise ValueError(f"cmap: expected a matplotlib colour map name, got {cmap!r}")
    cyc = check_positive(cycle, "cycle")
    ins = check_array(inside, "inside", shape=(3,))
    inner = ~np.isfinite(cnt)
    t = np.where(inner, 0.0, np.mod(np.where(inner, 0.0, cnt), cyc) / cyc)
    rgb = colormaps[cmap](t)[..., :3]
    rgb[inner] = ins
    return np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8)
