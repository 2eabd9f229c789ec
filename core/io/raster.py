"""Elevation rasters (DTM, CHM) as GeoTIFF through rasterio, with their coordinate system.

In memory a raster is a :class:`Raster`: a ``(rows, cols)`` float64 grid whose row ``i``,
column ``j`` is the cell centred at ``(x0 + j * res, y0 + i * res)`` -- rows run along +y
like the heightfields of :mod:`procgen.terrain`. On disk it is a north-up GeoTIFF (first
row northmost), float32, NaN as nodata, with the CRS as WKT when there is one.

>>> import numpy as np, tempfile, pathlib
>>> r = Raster(np.arange(6.0).reshape(2, 3), x0=512000.5, y0=5.4e6 + 0.5, res=1.0)
>>> p = pathlib.Path(tempfile.mkdtemp()) / "dtm.tif"
>>> _ = write_raster(p, r)
>>> back = read_raster(p)
>>> back.values.tolist(), back.x0, back.y0
([[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]], 512000.5, 5400000.5)
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError, check_array

__all__ = ["Raster", "write_raster", "read_raster"]


@dataclass
class Raster:
    """A grid of values over the plane.

    Attributes
    ----------
    values : (rows, cols) float64
        NaN where there is no value.
    x0, y0 : float
        Centre of cell ``[0, 0]`` (the south-west one), metres.
    res : float
        Cell size, metres.
    crs_wkt : str or None
    """

    values: np.ndarray
    x0: float
    y0: float
    res: float
    crs_wkt: str | None = None

    def __post_init__(self):
        self.values = check_array(self.values, "values", shape=(None, None), finite=False)
        if not self.res > 0:
            raise ValueError(f"res: expected a positive cell size, got {self.res}")

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell centre coordinates ``(xs (cols,), ys (rows,))``."""
        r, c = self.values.shape
        return self.x0 + self.res * np.arange(c), self.y0 + self.res * np.arange(r)

    def sample(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Bilinear values at points ``x, y (n,)``; NaN outside the grid or next to NaN."""
        x = np.asarray(x, np.float64)
        y = np.asarray(y, np.float64)
        r, c = self.values.shape
        u = (x - self.x0) / self.res
        v = (y - self.y0) / self.res
        inside = (u >= 0) & (u <= c - 1) & (v >= 0) & (v <= r - 1)
        j = np.clip(np.floor(u).astype(np.int64), 0, max(c - 2, 0))
        i = np.clip(np.floor(v).astype(np.int64), 0, max(r - 2, 0))
        fu = np.clip(u - j, 0, 1)
        fv = np.clip(v - i, 0, 1)
        z = self.values
        j1 = np.minimum(j + 1, c - 1)
        i1 = np.minimum(i + 1, r - 1)
        out = ((1 - fu) * (1 - fv) * z[i, j] + fu * (1 - fv) * z[i, j1]
               + (1 - fu) * fv * z[i1, j] + fu * fv * z[i1, j1])
        return np.where(inside, out, np.nan)


def write_raster(path: str | os.PathLike, raster: Raster) -> Path:
    """Write a north-up float32 GeoTIFF (deflate), atomically."""
    import rasterio
    from affine import Affine
    from rasterio.crs import CRS

    rows, cols = raster.values.shape
    west = raster.x0 - raster.res / 2
    north = raster.y0 + (rows - 0.5) * raster.res
    crs = CRS.from_wkt(raster.crs_wkt) if raster.crs_wkt else None
    with atomic_file(path) as tmp:
        with rasterio.open(tmp, "w", driver="GTiff", height=rows, width=cols, count=1,
                           dtype="float32", crs=crs, nodata=np.nan, compress="deflate",
                           transform=Affine(raster.res, 0.0, west, 0.0, -raster.res, north)) as dst:
            dst.write(raster.values[::-1].astype(np.float32), 1)
    return Path(path)


def read_raster(path: str | os.PathLike) -> Raster:
    """Read a single-band GeoTIFF written north-up with square cells."""
    import rasterio

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        with rasterio.open(path) as src:
            t = src.transform
            if t.b != 0 or t.d != 0 or t.e >= 0 or abs(t.a + t.e) > 1e-9 * abs(t.a):
                raise InputError("expected a north-up raster with square cells", path=path,
                                 field="transform")
            z = src.read(1).astype(np.float64)
            if src.nodata is not None and not np.isnan(src.nodata):
                z[z == src.nodata] = np.nan
            crs = src.crs.to_wkt() if src.crs else None
            rows = src.height
    except InputError:
        raise
    except Exception as e:
        raise InputError(f"not a readable GeoTIFF ({e})", path=path) from None
    res = float(t.a)
    return Raster(z[::-1], x0=float(t.c) + res / 2, y0=float(t.f) - (rows - 0.5) * res,
                  res=res, crs_wkt=crs)
