"""Blocks and lots: the land between the roads, cut into lots that each front a street.

Parish and Mueller (2001, section 4) take the blocks that the roads enclose and subdivide
them recursively, each time across the longest side, until the parts are small enough;
parts with no access to a street are discarded. Here the roads are ribbons of their
width; the land is the map less water, parks and roads, kept within ``lot_depth`` of a
road (so blocks the roads do not close still get their street-side lots); each block is cut
across the longest side of its minimum rotated rectangle until a part is no larger than
a lot; a part is a lot when its boundary touches a road (its *frontage*) along at least
``min_frontage`` metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon, box

__all__ = ["Lot", "road_area", "subdivide_lots"]


@dataclass(frozen=True)
class Lot:
    """A lot: its polygon and the street it fronts.

    ``polygon`` is a shapely Polygon (metres); ``front (2, 2)`` the stretch of its boundary
    along the road (the longest one), ``front_normal (2,)`` the unit vector from the lot
    towards that road, ``road`` the index of the road segment it fronts.
    """

    polygon: Polygon
    front: np.ndarray
    front_normal: np.ndarray
    road: int


def road_area(nodes: np.ndarray, edges: np.ndarray, half_widths: np.ndarray):
    """The roads as one area: each segment buffered by its half width (flat ends, round
    joins at the nodes), as a shapely geometry."""
    lines = [LineString([nodes[a], nodes[b]]).buffer(w, cap_style="round", join_style="round",
                                                    quad_segs=4)
             for (a, b), w in zip(edges, half_widths, strict=True)]
    return shapely.union_all(lines)


def _parts(geom):
    if geom.is_empty:
        return []
    if isinstance(geom, Polygon):
        return [geom]
    if isinstance(geom, MultiPolygon):
        return list(geom.geoms)
    return [g for g in getattr(geom, "geoms", []) if isinstance(g, Polygon)]


def _split(poly: Polygon, rng: np.random.Generator) -> list[Polygon]:
    """Cut ``poly`` across the longest side of its minimum rotated rectangle, near the
    middle."""
    rect = np.asarray(poly.minimum_rotated_rectangle.exterior.coords)[:4]
    e1, e2 = rect[1] - rect[0], rect[2] - rect[1]
    long_, short = (e1, e2) if np.hypot(*e1) >= np.hypot(*e2) else (e2, e1)
    t = rng.uniform(0.42, 0.58)
    u = long_ / np.hypot(*long_)
    n = short / max(np.hypot(*short), 1e-12)
    start = rect[0] if long_ is e1 else rect[1]
    mid = start + t * long_
    reach = 2 * (np.hypot(*long_) + np.hypot(*short))
    half_a = Polygon([mid - reach * n - reach * u, mid + reach * n - reach * u,
                      mid + reach * n, mid - reach * n])
    a = poly.intersection(half_a)
    b = poly.difference(half_a)
    return _parts(a) + _parts(b)


def subdivide_lots(land, roads, road_lines: list, *, lot_area: float, min_area: float,
                   min_frontage: float, rng: np.random.Generator,
                   max_parts: int = 200000) -> list[Lot]:
    """Subdivide ``land`` (shapely area) into lots that front ``roads`` (shapely area).

    Parameters
    ----------
    land, roads : shapely geometries
    road_lines : list of (2, 2) arrays
        The road segments' axes, to name the segment a lot fronts.
    lot_area : float
        Parts larger than this (m^2) are cut again.
    min_area : float
        Smaller parts are not lots.
    min_frontage : float
        Metres of boundary a lot shares with a road at least.
    rng : numpy.random.Generator

    Returns
    -------
    list of Lot
    """
    reach = roads.buffer(0.5, quad_segs=2)
    stack = sorted(_parts(land), key=lambda p: (p.centroid.x, p.centroid.y))
    lots: list[Lot] = []
    axes = np.asarray(road_lines, np.float64).reshape(-1, 2, 2)
    visited = 0
    while stack and visited < max_parts:
        poly = stack.pop()
        visited += 1
        if poly.area < min_area or not poly.intersects(reach):
            continue
        if poly.area > lot_area:
            stack.extend(_split(poly, rng))
            continue
        # compactness: slivers and ragged corners are not lots
        rect = poly.minimum_rotated_rectangle
        if poly.area < 0.55 * rect.area:
            continue
        edge = poly.exterior.intersection(reach)
        if edge.is_empty or edge.length < min_frontage:
            continue
        segs = [np.asarray(g.coords) for g in getattr(edge, "geoms", [edge])
                if hasattr(g, "coords") and len(g.coords) >= 2]
        if not segs:
            continue
        longest = max(segs, key=lambda s: np.linalg.norm(np.diff(s, axis=0), axis=1).sum())
        front = np.array([longest[0], longest[-1]])
        mid = front.mean(0)
        ab = axes[:, 1] - axes[:, 0]
        t = np.clip(((mid - axes[:, 0]) * ab).sum(-1) / np.maximum((ab**2).sum(-1), 1e-12),
                    0, 1)
        k = int(np.argmin(np.linalg.norm(axes[:, 0] + t[:, None] * ab - mid, axis=1)))
        along = front[1] - front[0]
        normal = np.array([-along[1], along[0]]) / max(np.hypot(*along), 1e-12)
        if np.dot(np.asarray(poly.centroid.coords)[0] - mid, normal) > 0:
            normal = -normal                     # away from the lot, towards the street
        lots.append(Lot(poly, front, normal, k))
    return lots


def land_near_roads(size: float, roads, *, depth: float, water_mask, park_mask,
                    resolution: float = 5.0):
    """The buildable land: the map within ``depth`` of a road, less roads, water and
    parks (the masks are sampled on a grid of ``resolution`` metres and polygonised)."""
    half = size / 2
    area = box(-half, -half, half, half).intersection(roads.buffer(depth, quad_segs=2))
    area = area.difference(roads)
    blocked = _mask_polygons(size, water_mask, resolution) + _mask_polygons(
        size, park_mask, resolution)
    if blocked:
        area = area.difference(shapely.union_all(blocked).buffer(resolution))
    return area


def _mask_polygons(size: float, mask, resolution: float) -> list:
    """Cells where ``mask`` holds, as square polygons merged row by row."""
    half = size / 2
    n = max(int(np.ceil(size / resolution)), 1)
    c = -half + (np.arange(n) + 0.5) * size / n
    X, Y = np.meshgrid(c, c)
    m = np.asarray(mask(np.stack([X.ravel(), Y.ravel()], 1))).reshape(n, n)
    step = size / n
    out = []
    for i in range(n):
        row = np.flatnonzero(np.diff(np.concatenate([[0], m[i].astype(np.int8), [0]])))
        for a, b in zip(row[::2], row[1::2], strict=True):
            out.append(box(-half + a * step, c[i] - step / 2, -half + b * step,
                           c[i] + step / 2))
    return out
