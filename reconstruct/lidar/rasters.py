"""Terrain and canopy rasters from a classified point cloud.

- **DTM**: the ground points' Delaunay triangulation (TIN) sampled at the cell centres
  (lidR's ``tin()``); cells outside the ground's convex hull take the nearest ground point.
- **CHM**: every point's height above the DTM, the highest per cell; empty cells take the
  highest of their neighbours (a few passes), negative heights are 0.
- **DSM**: the highest elevation per cell, filled the same way: where a tree's top is on a
  slope (the CHM's highest cell of a crown lies downslope of its top, where the ground
  falls away under the crown's edge).

Rasters are :class:`core.io.raster.Raster` (cell ``[i, j]`` centred at ``x0 + j res``,
``y0 + i res``), in the coordinates of the points.

>>> import numpy as np
>>> rng = np.random.default_rng(1)
>>> xy = np.vstack([rng.uniform(0, 20, (500, 2)), [[0, 0], [20, 0], [0, 20], [20, 20]]])
>>> g = np.column_stack([xy, np.zeros(len(xy))])
>>> g[:, 2] = 100 + 0.2 * g[:, 0] - 0.1 * g[:, 1]
>>> dtm = dtm_from_ground(g, bounds=(0, 0, 20, 20), res=1.0)
>>> xs, ys = dtm.centres()
>>> bool(np.allclose(dtm.values, 100 + 0.2 * xs[None] - 0.1 * ys[:, None]))
True
"""

from __future__ import annotations

import numpy as np

from core.io.raster import Raster
from core.validate import check_array, check_positive

__all__ = ["grid_for", "dtm_from_ground", "canopy_height", "surface_model", "height_above"]


def grid_for(bounds, res: float) -> tuple[float, float, int, int]:
    """Cell centres covering ``bounds = (xmin, ymin, xmax, ymax)``: ``(x0, y0, rows, cols)``.

    The grid is aligned on multiples of ``res`` so that rasters of tiles line up.
    """
    r = check_positive(res, "res")
    xmin, ymin, xmax, ymax = (float(v) for v in bounds)
    x0 = (np.floor(xmin / r) + 0.5) * r
    y0 = (np.floor(ymin / r) + 0.5) * r
    cols = int(np.ceil((xmax - (x0 - r / 2)) / r))
    rows = int(np.ceil((ymax - (y0 - r / 2)) / r))
    return x0, y0, max(rows, 1), max(cols, 1)


def dtm_from_ground(ground: np.ndarray, *, bounds, res: float = 1.0,
                    crs_wkt: str | None = None) -> Raster:
    """Digital terrain model from ground points.

    Parameters
    ----------
    ground : (n, 3) float64
        At least 3 points not all on a line.
    bounds : (4,) float
        ``xmin, ymin, xmax, ymax`` of the raster.
    res : float
        Cell size, metres.

    Returns
    -------
    Raster
    """
    from scipy.interpolate import LinearNDInterpolator
    from scipy.spatial import QhullError, cKDTree

    from reconstruct.lidar.ground import delaunay_2d

    g = check_array(ground, "ground", shape=(None, 3), min_rows=3)
    x0, y0, rows, cols = grid_for(bounds, res)
    xs = x0 + res * np.arange(cols)
    ys = y0 + res * np.arange(rows)
    X, Y = np.meshgrid(xs, ys)
    q = np.column_stack([X.ravel(), Y.ravel()])
    # the TIN in a local frame (projected coordinates lose digits in the triangulation)
    c = g[:, :2].mean(axis=0)
    try:
        # (its transforms written out: scipy's LAPACK calls crawl on a loaded machine)
        z = LinearNDInterpolator(delaunay_2d(g[:, :2] - c), g[:, 2])(q - c)
    except QhullError:
        raise ValueError("ground: the ground points lie on a line; no terrain to "
                         "interpolate") from None
    gap = ~np.isfinite(z)
    if np.any(gap):
        _, k = cKDTree(g[:, :2] - c).query(q[gap] - c)
        z[gap] = g[k, 2]
    return Raster(z.reshape(rows, cols), x0=x0, y0=y0, res=float(res), crs_wkt=crs_wkt)


def height_above(dtm: Raster, points: np.ndarray) -> np.ndarray:
    """Height of points ``(n, 3)`` above the DTM (bilinear; the nearest cell outside)."""
    p = check_array(points, "points", shape=(None, 3))
    r, c = dtm.values.shape
    x = np.clip(p[:, 0], dtm.x0, dtm.x0 + (c - 1) * dtm.res)
    y = np.clip(p[:, 1], dtm.y0, dtm.y0 + (r - 1) * dtm.res)
    return p[:, 2] - dtm.sample(x, y)


def canopy_height(points: np.ndarray, dtm: Raster, *, fill_passes: int = 3) -> Raster:
    """Canopy height model on the DTM's grid: the highest point above ground per cell.

    Parameters
    ----------
    points : (n, 3) float64
        All points (ground included).
    dtm : Raster
    fill_passes : int
        Empty cells take the highest of their 8 neighbours, this many times; cells
        still empty are 0.

    Returns
    -------
    Raster
        Heights in metres, >= 0.
    """
    p = check_array(points, "points", shape=(None, 3))
    chm = _cell_max(p[:, :2], height_above(dtm, p), dtm, fill_passes=fill_passes)
    chm[~np.isfinite(chm)] = 0.0
    return Raster(np.maximum(chm, 0.0), x0=dtm.x0, y0=dtm.y0, res=dtm.res,
                  crs_wkt=dtm.crs_wkt)


def surface_model(points: np.ndarray, like: Raster, *, fill_passes: int = 3) -> Raster:
    """Digital surface model on the grid of ``like``: the highest elevation per cell.

    Parameters
    ----------
    points : (n, 3) float64
    like : Raster
        The grid (a DTM); its values are not used.
    fill_passes : int
        Empty cells take the highest of their 8 neighbours, this many times; cells
        still empty take ``like``'s value there.

    Returns
    -------
    Raster
        Elevations in metres.
    """
    p = check_array(points, "points", shape=(None, 3))
    dsm = _cell_max(p[:, :2], p[:, 2], like, fill_passes=fill_passes)
    gap = ~np.isfinite(dsm)
    dsm[gap] = like.values[gap]
    return Raster(dsm, x0=like.x0, y0=like.y0, res=like.res, crs_wkt=like.crs_wkt)


def _cell_max(xy: np.ndarray, value: np.ndarray, grid: Raster, *,
              fill_passes: int) -> np.ndarray:
    """The highest ``value`` of the points in each cell of ``grid`` (-inf where none after
    ``fill_passes`` passes of taking the highest of the 8 neighbours)."""
    from scipy.ndimage import maximum_filter

    r, c = grid.values.shape
    j = np.clip(np.round((xy[:, 0] - grid.x0) / grid.res).astype(np.int64), 0, c - 1)
    i = np.clip(np.round((xy[:, 1] - grid.y0) / grid.res).astype(np.int64), 0, r - 1)
    out = np.full(r * c, -np.inf)
    np.maximum.at(out, i * c + j, value)
    out = out.reshape(r, c)
    for _ in range(int(fill_passes)):
        empty = ~np.isfinite(out)
        if not np.any(empty):
            break
        out[empty] = maximum_filter(out, size=3, mode="nearest")[empty]
    return out
