"""Individual trees from a canopy height model: tops by local maxima, crowns by watershed.

Tops: the CHM is smoothed (Gaussian, ``smooth`` metres), and a cell is a tree top when it is
at least ``min_height`` tall and the highest within a disc whose diameter grows with its
height, ``window_base + window_slope * height`` (the variable window of Popescu and Wynne
2004, doi:10.14358/PERS.70.5.589). Crowns: a watershed of the inverted smoothed CHM from the
tops (flooding from the highest level down), within the cells at least ``min_height`` tall. A tree's
height is the highest raw CHM cell of its crown; its position the centre of its top cell.

>>> import numpy as np
>>> from core.io.raster import Raster
>>> xs = np.arange(40) * 0.5
>>> X, Y = np.meshgrid(xs, xs)
>>> bumps = [(5, 5, 20), (14, 12, 15)]
>>> z = sum(h * np.exp(-((X - x) ** 2 + (Y - y) ** 2) / 8) for x, y, h in bumps)
>>> t = detect_trees(Raster(z, x0=0.0, y0=0.0, res=0.5))
>>> np.round(np.column_stack([t["x"], t["y"], t["height"]]), 1).tolist()
[[5.0, 5.0, 20.0], [14.0, 12.0, 15.0]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from core.io.raster import Raster

__all__ = ["TreeOptions", "detect_trees"]


@dataclass
class TreeOptions(Config):
    """Options of the tree detection."""

    min_height: float = option(2.0, unit="m", range="[0, 100]",
                               help="tops and crowns are at least this tall")
    smooth: float = option(0.5, unit="m", range="[0, 10]",
                           help="Gaussian sigma of the CHM smoothing before detection")
    window_base: float = option(2.0, unit="m", range="[0, 50]",
                                help="local-maximum window diameter at height 0")
    window_slope: float = option(0.1, range="[0, 2]",
                                 help="window diameter grows by this many metres per metre "
                                      "of height")


def _disc_max(z: np.ndarray, radius_cells: int) -> np.ndarray:
    from scipy.ndimage import maximum_filter

    r = int(radius_cells)
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return maximum_filter(z, footprint=(xx ** 2 + yy ** 2) <= r * r + 1e-9, mode="nearest")


def _flood(height: np.ndarray, labels: np.ndarray, mask: np.ndarray, *, step: float):
    """Marker-controlled watershed by flooding: the water level falls from the highest
    top in ``step`` metres; at each level every labelled region grows into the unlabelled
    cells of ``mask`` at or above the level that touch it (8-neighbours), until none is
    left. Where two regions meet, the larger label takes the contested cell."""
    from scipy.ndimage import maximum_filter

    lab = labels.copy()
    top = float(height[lab > 0].max())
    bottom = float(height[mask].min()) if np.any(mask) else top
    for level in np.arange(top, bottom - step, -step):
        region = mask & (height >= level)
        while True:
            grow = region & (lab == 0)
            if not np.any(grow):
                break
            near = maximum_filter(lab, size=3, mode="constant")
            new = grow & (near > 0)
            if not np.any(new):
                break
            lab[new] = near[new]
    return lab


def detect_trees(chm: Raster, *, options: TreeOptions | None = None) -> dict:
    """Tree tops and crowns.

    Parameters
    ----------
    chm : Raster
        Canopy heights, metres.
    options : TreeOptions, optional

    Returns
    -------
    dict
        ``x, y, height, crown_area`` (k,) float64 in the raster's coordinates (m, m², sorted
        by height, tallest first) and ``crowns`` (rows, cols) int32: the tree (1-based) of
        each cell, 0 for none.
    """
    from scipy.ndimage import gaussian_filter

    o = options or TreeOptions()
    raw = np.nan_to_num(chm.values, nan=0.0)
    res = chm.res
    s = gaussian_filter(raw, o.smooth / res, mode="nearest") if o.smooth > 0 else raw
    tall = s >= o.min_height
    top = np.zeros(raw.shape, bool)
    # one maximum filter per window radius (in cells) actually needed
    diam = o.window_base + o.window_slope * s
    radii = np.maximum(np.round(diam / 2 / res).astype(np.int64), 1)
    for r in np.unique(radii[tall]):
        sel = tall & (radii == r)
        top |= sel & (s >= _disc_max(s, int(r)))
    # a flat plateau gives several equal maxima: keep one per connected plateau
    from scipy.ndimage import label

    lab, n = label(top, structure=np.ones((3, 3)))
    if n == 0:
        empty = np.empty(0)
        return {"x": empty, "y": empty, "height": empty, "crown_area": empty,
                "crowns": np.zeros(raw.shape, np.int32)}
    flat = np.flatnonzero(lab.ravel())
    first = flat[np.unique(lab.ravel()[flat], return_index=True)[1]]
    ti, tj = np.unravel_index(first, raw.shape)
    order = np.argsort(-s[ti, tj], kind="stable")
    ti, tj = ti[order], tj[order]
    k = len(ti)
    crowns = np.zeros(raw.shape, np.int32)
    crowns[ti, tj] = np.arange(1, k + 1)
    crowns = _flood(s, crowns, tall, step=max(0.05, 0.1 * o.smooth + 0.05))
    area = np.bincount(crowns.ravel(), minlength=k + 1)[1:] * res * res
    height = np.zeros(k + 1)
    np.maximum.at(height, crowns.ravel(), raw.ravel())
    height = np.maximum(height[1:], raw[ti, tj])
    return {"x": chm.x0 + tj * res, "y": chm.y0 + ti * res, "height": height,
            "crown_area": area.astype(np.float64), "crowns": crowns.astype(np.int32)}
