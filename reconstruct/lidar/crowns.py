"""Crowns as polygons: the cells of each tree's crown in a label raster, traced as rings.

The crown raster (:func:`reconstruct.lidar.trees.detect_trees`' ``crowns``: the tree of
each cell, 0 for none) is traced cell edge by cell edge (rasterio's ``shapes``, GDAL's
polygonize), so a polygon covers exactly its crown's cells: its area is the crown's area,
and every cell centre of the crown (its top among them) lies inside it. A crown whose
cells touch only at corners is several parts (a MultiPolygon).

>>> import numpy as np
>>> from core.io.raster import Raster
>>> lab = np.zeros((4, 5), np.int32); lab[1:3, 1:3] = 1; lab[0, 4] = 2
>>> polys = crown_polygons(lab, Raster(np.zeros((4, 5)), x0=100.25, y0=200.25, res=0.5))
>>> [round(polygon_area(p), 3) for p in polys]
[1.0, 0.25]
"""

from __future__ import annotations

import numpy as np

from core.io.raster import Raster
from core.validate import check_array

__all__ = ["crown_polygons", "polygon_area", "point_in_polygons"]


def crown_polygons(crowns: np.ndarray, grid: Raster) -> list[list[list[np.ndarray]]]:
    """Polygons of the crowns ``1..k`` of a label raster on ``grid``'s cells.

    Parameters
    ----------
    crowns : (rows, cols) int
        The crown of each cell (1-based), 0 for none.
    grid : Raster
        The cells' coordinates (cell ``[i, j]`` centred at ``x0 + j res, y0 + i res``).

    Returns
    -------
    list
        For each crown ``1..max(crowns)``: its polygons, each a list of closed rings
        ``(m, 2) float64`` (outer ring first, then holes), in ``grid``'s coordinates. A
        label with no cell has no polygon (an empty list).
    """
    from affine import Affine
    from rasterio.features import shapes

    lab = check_array(crowns, "crowns", shape=(None, None)).astype(np.int32)
    if lab.shape != grid.values.shape:
        raise ValueError(f"crowns: expected the grid's shape {grid.values.shape}, got "
                         f"{lab.shape}")
    k = int(lab.max(initial=0))
    out: list[list[list[np.ndarray]]] = [[] for _ in range(k)]
    if k == 0:
        return out
    # local coordinates while tracing (float64 corners of projected grids stay exact), then
    # moved to the grid's
    half = grid.res / 2
    transform = Affine(grid.res, 0.0, -half, 0.0, grid.res, -half)
    shift = np.array([grid.x0, grid.y0])
    for geom, value in shapes(lab, mask=lab > 0, connectivity=4, transform=transform):
        rings = [np.asarray(r, np.float64) + shift for r in geom["coordinates"]]
        out[int(value) - 1].append(rings)
    return out


def polygon_area(polygons: list[list[np.ndarray]]) -> float:
    """Area of a feature's polygons (outer rings less holes), by the shoelace formula about
    each ring's first vertex (projected coordinates keep their digits)."""
    total = 0.0
    for poly in polygons:
        for n, ring in enumerate(poly):
            r = ring - ring[0]
            a = 0.5 * abs(float(np.sum(r[:-1, 0] * r[1:, 1] - r[1:, 0] * r[:-1, 1])))
            total += a if n == 0 else -a
    return total


def point_in_polygons(xy: np.ndarray, polygons: list[list[np.ndarray]]) -> np.ndarray:
    """Whether points ``(n, 2)`` lie inside a feature's polygons (even-odd rule over all
    rings: inside an outer ring and not in one of its holes)."""
    p = check_array(xy, "xy", shape=(None, 2))
    inside = np.zeros(len(p), bool)
    for poly in polygons:
        for ring in poly:
            a, b = ring[:-1], ring[1:]
            for (x1, y1), (x2, y2) in zip(a, b, strict=True):
                cross = ((y1 > p[:, 1]) != (y2 > p[:, 1]))
                with np.errstate(divide="ignore", invalid="ignore"):
                    xi = x1 + (p[:, 1] - y1) * (x2 - x1) / (y2 - y1)
                inside ^= cross & (p[:, 0] < xi)
    return inside
