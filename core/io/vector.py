"""Polygons with attributes as an OGC GeoPackage (``.gpkg``), through pyogrio (GDAL).

A polygon layer in memory is a list of features, each a list of polygons (a feature may
have several parts), each a list of rings ``(m, 2) float64`` (the outer ring first, then
its holes; closed or not), and a dict of columns ``name -> (n,) array`` (numbers or
text). On disk it is one MultiPolygon layer with those columns and the CRS, which QGIS,
ArcGIS and GDAL open as they are. Geometries go to GDAL as ISO WKB
(:func:`multipolygon_wkb`).

>>> import numpy as np, tempfile, pathlib
>>> sq = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
>>> p = pathlib.Path(tempfile.mkdtemp()) / "crowns.gpkg"
>>> _ = write_polygons(p, [[[sq + [512000.0, 5.4e6]]]], {"tree_id": np.array([7])},
...                    layer="crowns")
>>> feats, cols = read_polygons(p)
>>> cols["tree_id"].tolist(), float(feats[0][0][0][:, 0].min())
([7], 512000.0)
"""

from __future__ import annotations

import os
import struct
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError

__all__ = ["write_polygons", "read_polygons", "multipolygon_wkb", "parse_multipolygon_wkb"]


def _closed(ring) -> np.ndarray:
    r = np.asarray(ring, np.float64).reshape(-1, 2)
    if len(r) and not np.array_equal(r[0], r[-1]):
        r = np.vstack([r, r[:1]])
    return r


def multipolygon_wkb(polygons: Sequence[Sequence[np.ndarray]]) -> bytes:
    """ISO WKB (little endian) of a MultiPolygon: ``polygons`` a list of polygons, each a
    list of rings ``(m, 2)``; rings are closed when they are not.

    >>> sq = [[[0, 0], [1, 0], [1, 1], [0, 1]]]
    >>> len(multipolygon_wkb([sq]))  # 9 + 9 + 4 + 5 points x 16
    102
    """
    out = [struct.pack("<BII", 1, 6, len(polygons))]
    for poly in polygons:
        out.append(struct.pack("<BII", 1, 3, len(poly)))
        for ring in poly:
            r = _closed(ring)
            out.append(struct.pack("<I", len(r)))
            out.append(r.astype("<f8").tobytes())
    return b"".join(out)


def parse_multipolygon_wkb(data: bytes) -> list[list[np.ndarray]]:
    """The polygons of a WKB Polygon or MultiPolygon (either byte order, 2-D):
    the inverse of :func:`multipolygon_wkb`."""
    pos = 0

    def head():
        nonlocal pos
        order = "<" if data[pos] == 1 else ">"
        kind, n = struct.unpack_from(order + "II", data, pos + 1)
        pos += 9
        return order, kind, n

    def polygon(order, n):
        nonlocal pos
        rings = []
        for _ in range(n):
            (m,) = struct.unpack_from(order + "I", data, pos)
            pos += 4
            rings.append(np.frombuffer(data, order + "f8", 2 * m, pos).reshape(m, 2).copy())
            pos += 16 * m
        return rings

    order, kind, n = head()
    if kind == 3:
        return [polygon(order, n)]
    if kind != 6:
        raise ValueError(f"data: expected a WKB Polygon (3) or MultiPolygon (6), got type {kind}")
    polys = []
    for _ in range(n):
        o, k, m = head()
        polys.append(polygon(o, m))
    return polys


def write_polygons(path: str | os.PathLike, features: Sequence, columns: Mapping[str, Sequence],
                   *, layer: str = "polygons", crs_wkt: str | None = None) -> Path:
    """Write a MultiPolygon layer as a GeoPackage, atomically.

    Parameters
    ----------
    path : path to a ``.gpkg``
    features : list of (list of polygons, each a list of rings (m, 2) float64)
    columns : mapping name -> (n,) array
        One value per feature: integers, floats or text.
    layer : str
    crs_wkt : str, optional
    """
    from pyogrio.raw import write

    n = len(features)
    cols = {k: np.asarray(v) for k, v in columns.items()}
    bad = {k: len(v) for k, v in cols.items() if len(v) != n}
    if bad:
        raise ValueError(f"columns: expected {n} values each (one per feature), got {bad}")
    geometry = np.empty(n, dtype=object)
    geometry[:] = [multipolygon_wkb(f) for f in features]
    data = [v.astype(np.int64) if np.issubdtype(v.dtype, np.integer) else
            v.astype(np.float64) if np.issubdtype(v.dtype, np.number) else v.astype(object)
            for v in cols.values()]
    import warnings

    from pyogrio import get_gdal_config_option, set_gdal_config_options

    # GeoPackage stamps the layer with the time of writing; a fixed stamp keeps the same
    # input the same bytes (GDAL's OGR_CURRENT_DATE, meant for reproducible files)
    before = get_gdal_config_option("OGR_CURRENT_DATE")
    set_gdal_config_options({"OGR_CURRENT_DATE": "2000-01-01T00:00:00.000Z"})
    try:
        with atomic_file(path) as tmp, warnings.catch_warnings():
            # a layer without a CRS is what the caller asked for (pyogrio warns of it)
            warnings.filterwarnings("ignore", message="'crs' was not provided")
            tmp.unlink()  # GDAL creates the file itself
            write(str(tmp), geometry, data, list(cols), layer=layer, driver="GPKG",
                  geometry_type="MultiPolygon", crs=crs_wkt, promote_to_multi=False)
    finally:
        set_gdal_config_options({"OGR_CURRENT_DATE": before})
    return Path(path)


def read_polygons(path: str | os.PathLike, *, layer: str | None = None
                  ) -> tuple[list, dict[str, np.ndarray]]:
    """Read a polygon layer of a GeoPackage (or any vector file GDAL reads):
    ``(features, columns)`` as :func:`write_polygons` takes them."""
    from pyogrio.errors import DataSourceError
    from pyogrio.raw import read

    path = Path(path)
    try:
        meta, _, geometry, data = read(str(path), layer=layer)
    except DataSourceError as e:
        raise InputError(f"not a vector file GDAL reads ({e})", path=path,
                         field="layer") from None
    feats = [parse_multipolygon_wkb(bytes(g)) for g in geometry]
    return feats, {k: np.asarray(v) for k, v in zip(meta["fields"], data, strict=True)}
