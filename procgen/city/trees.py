"""The city's trees: Weber & Penn species trees (:mod:`procgen.weber_penn`) in rows along
its streets and scattered in its parks, instanced (:func:`procgen.weber_penn.grow_stand`).

Street trees stand on both verges of every street (highways too), ``verge`` metres beyond
the roadway's edge, every ``spacing`` metres along it (the first half a spacing from the
segment's start, so a row never starts in the crossing), wherever the spot is dry, off
every roadway and off every building's footprint. Park trees are a Poisson process of
``park_density`` per hectare over the parks, no two closer than half the mean spacing.
Each tree is drawn from the species list; its height is its species' own, ``Scale ±
ScaleV`` (the species file's, uniform; at least :data:`MIN_HEIGHT` of ``Scale``), so an
avenue of lombardy poplars is taller than one of sassafras, as in a real street.

>>> import numpy as np
>>> from procgen.city import CityConfig, generate_city
>>> cfg = CityConfig(size=300.0, max_segments=8, parks=0, river_width=0.0)
>>> city = generate_city(np.random.default_rng(0), cfg)
>>> trees = city_trees(city, rng=np.random.default_rng(1), species=["sycamore_maple"],
...                    spacing=15.0)
>>> len(trees.positions) > 10, trees.kind[:1].tolist()
(True, ['street'])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from core.validate import check_positive, check_range, check_rng
from procgen.city.lots import road_area
from procgen.weber_penn import Stand, grow_stand, load_species

__all__ = ["CityTrees", "city_trees", "MIN_HEIGHT"]

MIN_HEIGHT = 0.25
"""A tree is at least this share of its species' ``Scale`` (``ScaleV`` may equal it)."""


@dataclass
class CityTrees:
    """Trees of a city: ``positions`` (n, 3) stem bases (m), ``heights`` (n,), ``species``
    (n,) names, ``kind`` (n,) ``"street"`` or ``"park"``, and the instanced ``stand``
    (:class:`procgen.weber_penn.Stand`; :meth:`~procgen.weber_penn.Stand.mesh` for the
    triangles)."""

    positions: np.ndarray
    heights: np.ndarray
    species: np.ndarray
    kind: np.ndarray
    stand: Stand | None


def _street_spots(city, spacing: float, verge: float) -> np.ndarray:
    nodes, edges = city.nodes, city.edges
    half = city.half_widths()
    out = []
    for (i, j), hw in zip(edges, half, strict=True):
        p, q = nodes[i], nodes[j]
        d = q - p
        length = float(np.hypot(*d))
        if length < spacing:
            continue
        u = d / length
        n = np.array([-u[1], u[0]])
        s = np.arange(0.5 * spacing, length - 0.25 * spacing, spacing)
        for side in (-1.0, 1.0):
            out.append(p + s[:, None] * u + side * (hw + verge) * n)
    return np.vstack(out) if out else np.empty((0, 2))


def _park_spots(city, rng, density: float) -> np.ndarray:
    size = city.config.size
    n = int(rng.poisson(density * size * size / 1e4))
    if n == 0:
        return np.empty((0, 2))
    cand = rng.uniform(-size / 2, size / 2, (n, 2))
    cand = cand[np.asarray(city.park(cand), bool)]
    min_d = 0.5 * np.sqrt(1e4 / density)
    kept: list = []
    for p in cand:  # no two trees closer than half the mean spacing
        if not kept or np.min(np.hypot(*(np.array(kept) - p).T)) >= min_d:
            kept.append(p)
    return np.array(kept).reshape(-1, 2)


def city_trees(city, *, rng: np.random.Generator, species, spacing: float = 12.0,
               verge: float = 1.5, park_density: float = 0.0, variants: int = 2,
               lod: str = "cards") -> CityTrees:
    """Plant ``species`` (shipped names or ``.toml`` files) along ``city``'s streets every
    ``spacing`` metres, ``verge`` metres off the roadway, and ``park_density`` per hectare in
    its parks (see the module docstring); ``variants`` individuals a species are grown and
    instanced."""
    rng = check_rng(rng)
    names = [species] if isinstance(species, str) else list(species)
    if not names:
        raise ValueError("species: expected at least one species name or .toml file")
    params = {s: load_species(s) for s in names}
    spacing = check_positive(spacing, "spacing")
    verge = check_range(verge, "verge", 0.0, 100.0)
    park_density = check_range(park_density, "park_density", 0.0, 10_000.0)
    street = _street_spots(city, spacing, verge) if len(city.edges) else np.empty((0, 2))
    park = _park_spots(city, rng, park_density) if park_density > 0 else np.empty((0, 2))
    xy = np.vstack([street, park])
    kind = np.array(["street"] * len(street) + ["park"] * len(park))
    if len(xy):
        # dry, off the roadways and off the buildings (each tree's stem with a metre round it)
        blocked = road_area(city.nodes, city.edges, city.half_widths()) if len(city.edges) \
            else shapely.Polygon()
        if city.buildings:
            blocked = shapely.union_all([blocked, *[shapely.Polygon(b.footprint)
                                                    for b in city.buildings]])
        pts = shapely.points(xy)
        ok = ~shapely.intersects(blocked.buffer(1.0), pts) & ~np.asarray(city.water(xy), bool)
        xy, kind = xy[ok], kind[ok]
    which = rng.integers(len(names), size=len(xy))
    chosen = np.array(names, dtype=object)[which] if len(xy) else np.empty(0, object)
    heights = np.array([max(params[s]["Scale"] + rng.uniform(-1, 1) * params[s]["ScaleV"],
                            MIN_HEIGHT * params[s]["Scale"]) for s in chosen]).reshape(-1)
    pos = np.column_stack([xy, np.zeros(len(xy))]) if len(xy) else np.empty((0, 3))
    stand = (grow_stand(list(chosen), pos, heights, rng=rng, variants=variants, lod=lod)
             if len(xy) else None)
    return CityTrees(pos, heights, np.array(chosen, str), kind, stand)
