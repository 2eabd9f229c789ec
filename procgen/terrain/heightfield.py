"""Terrain: heightfields to meshes, water by an elevation threshold, fractal-noise and
tileable terrains.

Heightfields are ``(rows, cols)`` arrays; sample ``[i, j]`` sits at
``origin + (j * dx, i * dy, heights[i, j])`` (rows along +y, columns along +x, Z up).

>>> import numpy as np
>>> mesh = heightfield_to_mesh(np.zeros((3, 4)), spacing=0.5)
>>> len(mesh.vertices), len(mesh.triangles)
(12, 12)
"""

from __future__ import annotations

import numpy as np

from core.meshes import make_mesh
from core.validate import (
    check_array,
    check_choice,
    check_finite,
    check_int,
    check_positive,
    check_rng,
)
from procgen.fractals.displacement import _check_hurst, diamond_square
from procgen.noise.fractal import fbm, ridged, tileable

__all__ = ["heightfield_to_mesh", "water_mesh", "fractal_terrain", "tileable_terrain",
           "mountain_relief", "mean_slope",
           "check_grid_size"]


def check_grid_size(size, name: str = "size") -> int:
    """Return ``n`` for a grid size ``2**n + 1`` (n >= 1); a ValueError naming ``name`` else."""
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise ValueError(f"{name}: expected an integer 2**n + 1, got {size!r}")
    m = int(size) - 1
    if m < 2 or m & (m - 1):
        raise ValueError(f"{name}: expected a grid size 2**n + 1 (3, 5, 9, 17, ...), got {size}")
    return m.bit_length() - 1


def _spacing(spacing):
    s = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (2,)).copy()
    for v in s:
        check_positive(v, "spacing")
    return s


def _grid_args(heights, spacing, origin):
    """Checked heights (at least 2 x 2), spacing (2,) and origin (3,)."""
    z = check_array(heights, "heights", shape=(None, None))
    if z.shape[0] < 2 or z.shape[1] < 2:
        raise ValueError(f"heights: expected at least a 2 x 2 grid, got shape {z.shape}")
    return z, _spacing(spacing), check_array(origin, "origin", shape=(3,))


def _grid_triangles(rows: int, cols: int) -> np.ndarray:
    idx = np.arange(rows * cols).reshape(rows, cols)
    a = idx[:-1, :-1].ravel()
    b = idx[:-1, 1:].ravel()
    c = idx[1:, :-1].ravel()
    d = idx[1:, 1:].ravel()
    # counter-clockwise seen from +z: (a, b, d) and (a, d, c)
    return np.stack([np.stack([a, b, d], 1), np.stack([a, d, c], 1)], 1).reshape(-1, 3)


def heightfield_to_mesh(heights, *, spacing=1.0, origin=(0.0, 0.0, 0.0)):
    """Triangulate a heightfield: an open3d mesh with vertex normals and UVs.

    Parameters
    ----------
    heights : (r, c) float64
        Finite heights, r, c >= 2.
    spacing : float or (2,) float
        Grid step ``(dx, dy)`` in metres.
    origin : (3,) float
        Position of sample ``[0, 0]`` at height 0.

    Returns
    -------
    open3d.geometry.TriangleMesh
        ``r * c`` vertices, ``2 (r - 1)(c - 1)`` triangles facing +z, vertex normals and
        ``triangle_uvs`` (u along columns, v along rows, both in [0, 1]).
    """
    import open3d as o3d

    z, d, o = _grid_args(heights, spacing, origin)
    rows, cols = z.shape
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    verts = np.stack([o[0] + jj.ravel() * d[0], o[1] + ii.ravel() * d[1], o[2] + z.ravel()], 1)
    tris = _grid_triangles(rows, cols)
    mesh = make_mesh(verts, tris)
    uv = np.stack([jj.ravel() / (cols - 1), ii.ravel() / (rows - 1)], 1)
    mesh.triangle_uvs = o3d.utility.Vector2dVector(uv[tris.ravel()])
    return mesh


def water_mesh(heights, level, *, spacing=1.0, origin=(0.0, 0.0, 0.0)):
    """A water surface over the terrain.

    ``level`` is a height (a flat sheet over every cell whose lowest corner is below it)
    or a ``(rows, cols)`` grid of water surface heights, NaN where dry (water that
    follows the flow: :func:`procgen.terrain.materials.water_surface`); a cell with any
    wet corner is covered, its dry corners at the bank's height.

    Returns an open3d mesh (facing +z, with UVs like :func:`heightfield_to_mesh`); it has
    no triangles when the terrain is nowhere under water.
    """
    import open3d as o3d

    z, d, o = _grid_args(heights, spacing, origin)
    rows, cols = z.shape
    if np.ndim(level) == 0:
        lv = check_finite(level, "level")
        cmin = np.minimum(np.minimum(z[:-1, :-1], z[:-1, 1:]), np.minimum(z[1:, :-1], z[1:, 1:]))
        wet_cell = cmin < lv
        surface = np.full(z.shape, lv)
    else:
        lv = check_array(level, "level", shape=z.shape, finite=False)
        w = np.isfinite(lv)
        wet_cell = w[:-1, :-1] | w[:-1, 1:] | w[1:, :-1] | w[1:, 1:]
        surface = np.where(w, lv, z)
    wet = np.repeat(wet_cell.ravel(), 2)
    tris = _grid_triangles(rows, cols)[wet]
    used = np.unique(tris)
    remap = np.full(rows * cols, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    ii, jj = np.divmod(used, cols)
    verts = np.stack([o[0] + jj * d[0], o[1] + ii * d[1], o[2] + surface.ravel()[used]], 1)
    new_tris = remap[tris].reshape(-1, 3)
    mesh = make_mesh(verts.reshape(-1, 3), new_tris,
                     compute_normals=np.ndim(level) != 0 and len(new_tris) > 0)
    if len(new_tris):
        if np.ndim(level) == 0:
            mesh.vertex_normals = o3d.utility.Vector3dVector(
                np.tile([0.0, 0.0, 1.0], (len(used), 1)))
        uv = np.stack([jj / (cols - 1), ii / (rows - 1)], 1)
        mesh.triangle_uvs = o3d.utility.Vector2dVector(uv[new_tris.ravel()])
    return mesh


def _seed_from(rng) -> int:
    check_rng(rng)
    return int(rng.integers(0, 2 ** 31 - 1))


def fractal_terrain(size: int, *, rng: np.random.Generator, method: str = "diamond_square",
                    hurst: float = 0.8, height: float = 1.0, frequency: float = 4.0,
                    octaves: int = 8) -> np.ndarray:
    """A fractal heightfield of ``size x size`` samples over the unit square.

    Parameters
    ----------
    size : int
        Samples a side, ``2**n + 1``.
    rng : numpy.random.Generator
    method : {'diamond_square', 'fbm', 'ridged'}
        Saupe's midpoint displacement (with the addition step), fBm of Perlin noise, or
        Musgrave's ridged multifractal (mountain ridges).
    hurst : float
        Hurst exponent in (0, 1): roughness of diamond-square; for the noise methods the
        octave gain is ``2**-hurst``.
    height : float
        Vertical scale: the result has standard deviation ``height`` (peak-to-peak
        about 6 times that).
    frequency : float
        Noise methods: lattice cells across the square in the first octave.
    octaves : int
        Noise methods: number of octaves.

    Returns
    -------
    (size, size) float64, zero mean

    Examples
    --------
    >>> z = fractal_terrain(33, rng=np.random.default_rng(0), method="fbm")
    >>> z.shape
    (33, 33)
    """
    n = check_grid_size(size)
    method = check_choice(method, "method", {"diamond_square", "fbm", "ridged"})
    h = _check_hurst(hurst)
    amp = check_positive(height, "height", allow_zero=True)
    f = check_positive(frequency, "frequency")
    if method == "diamond_square":
        z = diamond_square(n, hurst=h, rng=rng, addition=True)
    else:
        seed = _seed_from(rng)
        shift = rng.uniform(0, 256, size=2)
        u = np.linspace(0.0, 1.0, size)
        x = f * u[None, :] + shift[0]
        y = f * u[:, None] + shift[1]
        if method == "fbm":
            z = fbm(x, y, 0.5, octaves=octaves, gain=2.0 ** -h, seed=seed)
        else:
            z = ridged(x, y, 0.5, octaves=octaves, h=h, seed=seed)
    z = z - z.mean()
    sd = z.std()
    return z * (amp / sd) if sd > 0 else z


def tileable_terrain(size: int, *, rng: np.random.Generator, frequency: int = 4,
                     octaves: int = 6, hurst: float = 0.8, height: float = 1.0) -> np.ndarray:
    """A heightfield that tiles: its last row and column equal its first.

    Samples ``u = j / (size - 1)`` of :func:`procgen.noise.tileable` (period 1), so copies
    placed edge to edge share their border samples exactly and the seam is invisible.

    Returns
    -------
    (size, size) float64, zero mean, standard deviation ``height``
    """
    size = check_int(size, "size", 3)
    h = _check_hurst(hurst)
    amp = check_positive(height, "height", allow_zero=True)
    seed = _seed_from(rng)
    u = np.arange(size) / (size - 1)
    z = tileable(u[None, :], u[:, None], frequency=frequency, octaves=octaves, gain=2.0 ** -h,
                 seed=seed)
    # u = 1 is u = 0 up to rounding of u * period: make the seam exact
    z[:, -1] = z[:, 0]
    z[-1, :] = z[0, :]
    z = z - z.mean()
    sd = z.std()
    return z * (amp / sd) if sd > 0 else z


def mountain_relief(base, *, spacing: float, rng: np.random.Generator, slope: float = 0.0,
                    aspect: float = 180.0, slope_breaks: int = 0, terraces: int = 0,
                    cliffs: int = 0, cliff_height: float = 4.0, ravines: int = 0,
                    ravine_depth: float = 3.0, boulders: float = 0.0,
                    region=None) -> np.ndarray:
    """A heightfield with the relief of a mountainside: a tilt, breaks of slope, terraces,
    cliffs, ravines and boulders over ``base``.

    The features are laid along the fall line ``u`` (horizontal distance downhill, towards
    ``aspect``) and across it ``v``; each line across the slope (a break, a terrace's edge,
    a cliff) wanders with a seeded sine of ``v`` so that none is straight.

    - **Tilt and breaks of slope**: the terrain drops ``tan(t) * P(u)`` downhill, ``P`` a
      profile whose gradient is 1 on average and changes at ``slope_breaks`` places (a
      kink: the gradient alternates between 1.6 and 0.6 before normalising) and, with ``terraces``,
      alternates between benches (gradient 0.15) and risers (the rest) ``terraces``
      times across the stand.
    - **Cliffs**: ``cliffs`` steps of ``cliff_height`` each, down the fall line, over one
      grid spacing (a face of ``atan(cliff_height / spacing)``).
    - **Ravines**: ``ravines`` V-shaped gullies down the fall line, ``ravine_depth`` deep
      and ``4 x ravine_depth`` across, meandering.
    - **Boulders**: ``boulders`` per hectare, ellipsoidal caps 0.5-1.5 m in radius and
      0.5-1.2 times as high, on the ground.

    The tilt ``t`` is found (bisection) so that the mean slope of the result over
    ``region`` -- the mean of ``atan |grad z|`` over the grid's cells, relief and
    features included -- is ``slope`` degrees; when the features alone are steeper the
    tilt is 0. ``slope`` 0 is no tilt (and no breaks or terraces).

    Parameters
    ----------
    base : (r, c) float64
        Heights (metres), sample ``[i, j]`` at ``(j * spacing, i * spacing)``.
    spacing : float
        Metres.
    rng : numpy.random.Generator
    slope : float
        Degrees in [0, 80).
    aspect : float
        Degrees clockwise from +y (north) the slope faces.
    region : (4,) float, optional
        ``xmin, ymin, xmax, ymax`` of the cells (grid coordinates, metres) whose mean
        slope is ``slope``; default the whole grid.

    Returns
    -------
    (r, c) float64

    >>> z = mountain_relief(np.zeros((65, 65)), spacing=1.0, slope=30.0,
    ...                     rng=np.random.default_rng(0))
    >>> round(mean_slope(z, 1.0), 6)
    30.0
    """
    z0 = check_array(base, "base", shape=(None, None))
    h = check_positive(spacing, "spacing")
    check_rng(rng)
    s = check_finite(slope, "slope")
    if not 0 <= s < 80:
        raise ValueError(f"slope: expected degrees in [0, 80), got {slope!r}")
    for name, v in (("slope_breaks", slope_breaks), ("terraces", terraces),
                    ("cliffs", cliffs), ("ravines", ravines)):
        check_int(v, name, 0)
    check_positive(cliff_height, "cliff_height")
    check_positive(ravine_depth, "ravine_depth")
    check_positive(boulders, "boulders", allow_zero=True)
    rows, cols = z0.shape
    a = np.radians(check_finite(aspect, "aspect"))
    X, Y = np.meshgrid(np.arange(cols) * h, np.arange(rows) * h)
    cx, cy = X.mean(), Y.mean()
    down = np.array([np.sin(a), np.cos(a)])
    u = (X - cx) * down[0] + (Y - cy) * down[1]
    v = -(X - cx) * down[1] + (Y - cy) * down[0]
    umin, umax = float(u.min()), float(u.max())
    length = max(umax - umin, h)

    def wander(amp, along=v):  # a line's offset: a seeded sine of the coordinate along it
        k, ph = rng.uniform(0.5, 1.5) * 2 * np.pi / length, rng.uniform(0, 2 * np.pi)
        return amp * np.sin(k * along + ph)

    # the profile's gradient along u: breaks (kinks) and terraces (benches and risers)
    grad = np.ones_like(u)
    if slope_breaks:
        at = np.sort(rng.uniform(umin, umax, int(slope_breaks)))
        passed = sum(((u + wander(0.05 * length)) > b).astype(np.int64) for b in at)
        steep_first = rng.uniform() < 0.5
        grad = np.where((passed % 2 == 0) == steep_first, 1.6, 0.6)
    if terraces:
        period = length / int(terraces)
        phase = ((u + wander(0.05 * length) - umin) / period + rng.uniform()) % 1.0
        grad = grad * np.where(phase < 0.5, 0.15, 1.85)
    grad = grad / grad.mean()
    # P(u): the integral of the gradient down every column of the fall line, on the grid
    order = np.argsort(u, axis=None)
    us, gs = u.ravel()[order], grad.ravel()[order]
    prof = np.empty(u.size)
    prof[order] = np.concatenate([[0.0], np.cumsum(0.5 * (gs[1:] + gs[:-1]) * np.diff(us))])
    prof = prof.reshape(u.shape)
    prof -= prof.mean()
    feat = z0.copy()
    for _ in range(int(cliffs)):
        at = rng.uniform(umin + 0.2 * length, umax - 0.2 * length)
        t = np.clip((u + wander(0.08 * length) - at) / h + 0.5, 0.0, 1.0)
        feat -= cliff_height * t * t * (3 - 2 * t)
    for _ in range(int(ravines)):
        at = rng.uniform(-0.35, 0.35) * length
        centre = at + wander(0.1 * length, u)
        w = 2.0 * ravine_depth
        feat -= ravine_depth * np.clip(1.0 - np.abs(v - centre) / w, 0.0, None)
    m = int(rng.poisson(boulders * rows * cols * h * h / 1e4))
    for _ in range(m):
        px, py = rng.uniform(0, (cols - 1) * h), rng.uniform(0, (rows - 1) * h)
        r = rng.uniform(0.5, 1.5)
        top = r * rng.uniform(0.5, 1.2)
        d2 = ((X - px) ** 2 + (Y - py) ** 2) / r ** 2
        feat += top * np.sqrt(np.clip(1.0 - d2, 0.0, None))
    if s == 0:
        return feat
    sel = None
    if region is not None:
        x0, y0, x1, y1 = (float(c) for c in region)
        xc, yc = X[:-1, :-1] + h / 2, Y[:-1, :-1] + h / 2
        sel = (xc >= x0) & (xc <= x1) & (yc >= y0) & (yc <= y1)

    def mean_at(tan_t):
        return mean_slope(feat - tan_t * prof, h, where=sel)

    want = s
    if mean_at(0.0) >= want:
        return feat
    lo, hi = 0.0, 1.0
    while mean_at(hi) < want:
        hi *= 2
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mean_at(mid) < want else (lo, mid)
    return feat - 0.5 * (lo + hi) * prof


def mean_slope(heights, spacing: float, *, where=None) -> float:
    """Mean slope of a heightfield in degrees: ``atan`` of the gradient's magnitude on
    each grid cell (its two triangles' mean gradient: forward differences averaged over
    the cell's edges), averaged over the cells (or those of the ``(r-1, c-1)`` mask
    ``where``)."""
    z = check_array(heights, "heights", shape=(None, None))
    h = check_positive(spacing, "spacing")
    gx = 0.5 * ((z[:-1, 1:] - z[:-1, :-1]) + (z[1:, 1:] - z[1:, :-1])) / h
    gy = 0.5 * ((z[1:, :-1] - z[:-1, :-1]) + (z[1:, 1:] - z[:-1, 1:])) / h
    ang = np.degrees(np.arctan(np.hypot(gx, gy)))
    return float(ang[where].mean() if where is not None else ang.mean())
