"""The city as GIS tools read it: GeoJSON roads, lots and buildings, and CityJSON LoD2.

GeoJSON (RFC 7946) files hold the city in metres in its own plan frame (x east, y north);
RFC 7946 asks for WGS84 longitudes and latitudes, so the files carry no ``crs`` member and
GeoPandas/OSMnx read them as plain planar coordinates (``GeoDataFrame.set_crs`` places
them). CityJSON 2.0 (https://www.cityjson.org/specs/2.0.1/) holds each building as a
``Building`` with one LoD 2.2 ``Solid``: the ground, wall and roof surfaces of the mass and
its roof, with their semantics, outward oriented, on integer vertices with a transform.
:func:`check_cityjson` checks what cjval checks of a file's structure and geometry that
needs no schema download: the version and types, vertex indices in range, no unused or
duplicate vertices, semantics matching the surfaces, and each solid closed and outward.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from core.files import write_json

__all__ = ["city_geojson", "city_cityjson", "write_city_files", "check_cityjson",
           "CITY_SUFFIXES", "city_paths"]

CITY_SUFFIXES = (".roads.geojson", ".lots.geojson", ".buildings.geojson", ".city.json")


def city_paths(out: Path) -> list[Path]:
    """The files written beside ``out`` (``city.ply`` -> ``city.roads.geojson`` ...)."""
    out = Path(out)
    stem = out.name[: -len(out.suffix)] if out.suffix else out.name
    return [out.with_name(stem + s) for s in CITY_SUFFIXES]


def _collection(features) -> dict:
    return {"type": "FeatureCollection", "features": features}


def _ring(coords) -> list:
    c = [[round(float(x), 3), round(float(y), 3)] for x, y in np.asarray(coords)[:, :2]]
    if c[0] != c[-1]:
        c.append(c[0])
    return c


def city_geojson(city) -> dict:
    """``{"roads": ..., "lots": ..., "buildings": ...}`` as GeoJSON FeatureCollections."""
    roads = []
    for k, ((i, j), hw) in enumerate(zip(city.edges, city.highway, strict=True)):
        roads.append({"type": "Feature", "id": k,
                      "properties": {"kind": "highway" if hw else "street",
                                     "width_m": float(2 * city.half_widths()[k]),
                                     "u": int(i), "v": int(j)},
                      "geometry": {"type": "LineString",
                                   "coordinates": [[round(float(x), 3), round(float(y), 3)]
                                                   for x, y in city.nodes[[i, j]]]}})
    lots = []
    for k, lot in enumerate(city.lots):
        lots.append({"type": "Feature", "id": k,
                     "properties": {"area_m2": round(float(lot.polygon.area), 2),
                                    "road": int(lot.road),
                                    "frontage_m": round(float(np.linalg.norm(
                                        lot.front[1] - lot.front[0])), 2)},
                     "geometry": {"type": "Polygon",
                                  "coordinates": [_ring(lot.polygon.exterior.coords)]}})
    buildings = []
    for k, b in enumerate(city.buildings):
        buildings.append({"type": "Feature", "id": k,
                          "properties": {"height_m": round(float(b.ridge), 3),
                                         "eave_m": round(float(b.height), 3),
                                         "floors": int(b.floors), "roof": b.roof,
                                         "lot": int(b.lot), "rules": b.rules,
                                         "windows": int(sum(b.windows.values())),
                                         "doors": int(sum(b.doors.values()))},
                          "geometry": {"type": "Polygon", "coordinates": [_ring(b.footprint)]}})
    return {"roads": _collection(roads), "lots": _collection(lots),
            "buildings": _collection(buildings)}


def _lod2_surfaces(b) -> tuple[list, list]:
    """The LoD2 solid of a building: polygons ``(k, 3)`` (outward, counter-clockwise seen
    from outside) and their semantic types."""
    from procgen.city.cga import BuildingGeometry, Scope, emit_roof

    fp = np.asarray(b.footprint, np.float64)
    h = float(b.height)
    low = np.c_[fp, np.zeros(4)]
    high = np.c_[fp, np.full(4, h)]
    polys, kinds = [low[::-1]], ["GroundSurface"]
    for i in range(4):
        j = (i + 1) % 4
        polys.append(np.array([low[i], low[j], high[j], high[i]]))
        kinds.append("WallSurface")
    X = np.array([*(fp[1] - fp[0]), 0.0])
    Y = np.array([*(fp[3] - fp[0]), 0.0])
    sx, sy = np.linalg.norm(X), np.linalg.norm(Y)
    top = Scope(high[0], np.stack([X / sx, Y / sy, [0.0, 0.0, 1.0]], 1), np.array([sx, sy, 0]))
    geo = BuildingGeometry()
    emit_roof(geo, top, b.roof, np.radians(b.pitch) if b.roof != "flat" else 0.0)
    for poly, lab in zip(geo.polygons, geo.labels, strict=True):
        polys.append(poly)
        kinds.append("RoofSurface" if lab == 4 else "WallSurface")
    if b.roof == "gable":     # a gable's end triangle and the wall under it: one pentagon
        merged, mk = [polys[0]], [kinds[0]]
        walls = polys[1:5]
        ends = polys[7:9]
        for w in walls:
            for e in ends:
                shared = [p for p in e if np.any(np.all(np.isclose(w, p), axis=1))]
                if len(shared) == 2:
                    apex = next(p for p in e if not np.any(np.all(np.isclose(w, p), axis=1)))
                    w = np.array([w[0], w[1], w[2], apex, w[3]])
            merged.append(w)
            mk.append("WallSurface")
        merged += polys[5:7]
        mk += ["RoofSurface", "RoofSurface"]
        polys, kinds = merged, mk
    return polys, kinds


def city_cityjson(city, *, scale: float = 0.001) -> dict:
    """The buildings as a CityJSON 2.0 document (LoD 2.2 solids with semantics)."""
    verts: list = []
    index: dict = {}

    def vid(p) -> int:
        key = tuple(int(round(c / scale)) for c in p)
        if key not in index:
            index[key] = len(verts)
            verts.append(list(key))
        return index[key]

    objects = {}
    for k, b in enumerate(city.buildings):
        polys, kinds = _lod2_surfaces(b)
        shell = [[[vid(p) for p in poly]] for poly in polys]
        types = sorted(set(kinds))
        objects[f"building-{k}"] = {
            "type": "Building",
            "attributes": {"measuredHeight": round(float(b.ridge), 3),
                           "storeysAboveGround": int(b.floors), "roofType": b.roof},
            "geometry": [{"type": "Solid", "lod": "2.2", "boundaries": [shell],
                          "semantics": {"surfaces": [{"type": t} for t in types],
                                        "values": [[types.index(t) for t in kinds]]}}]}
    return {"type": "CityJSON", "version": "2.0",
            "transform": {"scale": [scale] * 3, "translate": [0.0, 0.0, 0.0]},
            "metadata": {"title": "scanamp procgen city"},
            "CityObjects": objects, "vertices": verts}


def check_cityjson(doc: dict) -> list[str]:
    """Problems of a CityJSON document (empty when valid): structure, vertex indices,
    unused or duplicate vertices, semantics, and closed, outward solids."""
    errs = []
    if doc.get("type") != "CityJSON" or not str(doc.get("version", "")).startswith("2."):
        errs.append("type/version: expected CityJSON 2.x")
    verts = np.asarray(doc.get("vertices", []), np.float64).reshape(-1, 3)
    t = doc.get("transform", {})
    real = verts * np.asarray(t.get("scale", [1, 1, 1])) + np.asarray(t.get("translate",
                                                                             [0, 0, 0]))
    used = np.zeros(len(verts), bool)
    if len({tuple(v) for v in verts.tolist()}) != len(verts):
        errs.append("vertices: duplicate vertices")
    for name, obj in doc.get("CityObjects", {}).items():
        for g, geom in enumerate(obj.get("geometry", [])):
            where = f"CityObjects.{name}.geometry[{g}]"
            if geom.get("type") != "Solid":
                continue
            for s, shell in enumerate(geom["boundaries"]):
                vals = geom.get("semantics", {}).get("values", [[]])[s]
                if len(vals) != len(shell):
                    errs.append(f"{where}: semantics values do not match the surfaces")
                edges: dict = {}
                vol = 0.0
                for surface in shell:
                    ring = surface[0]
                    if min(ring) < 0 or max(ring) >= len(verts):
                        errs.append(f"{where}: vertex index out of range")
                        return errs
                    used[ring] = True
                    if len(set(ring)) != len(ring) or len(ring) < 3:
                        errs.append(f"{where}: degenerate ring {ring}")
                    for a, b in zip(ring, ring[1:] + ring[:1], strict=True):
                        edges[(a, b)] = edges.get((a, b), 0) + 1
                    p = real[ring]
                    for k in range(1, len(ring) - 1):
                        vol += np.dot(p[0], np.cross(p[k], p[k + 1])) / 6.0
                for (a, b), n in edges.items():
                    if n != 1 or edges.get((b, a), 0) != 1:
                        errs.append(f"{where}: shell not closed or not consistently oriented "
                                    f"at edge {a}-{b}")
                        break
                if vol <= 0:
                    errs.append(f"{where}: shell oriented inward (volume {vol:.3f})")
    if len(verts) and not used.all():
        errs.append(f"vertices: {int((~used).sum())} unused")
    return errs


def write_city_files(city, out: Path) -> list[Path]:
    """Write the GeoJSON and CityJSON files beside ``out`` (see :func:`city_paths`)."""
    gj = city_geojson(city)
    paths = city_paths(out)
    for path, key in zip(paths[:3], ("roads", "lots", "buildings"), strict=True):
        write_json(path, gj[key])
    write_json(paths[3], city_cityjson(city))
    return paths
