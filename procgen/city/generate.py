"""A procedural city: roads, blocks, lots and buildings from a split grammar.

The roads grow as Parish and Mueller (2001) grow them (:mod:`procgen.city.roads`: global
goals by ``pattern``, local constraints at water, parks and slopes), the land between them
is cut into lots that front a street (:mod:`procgen.city.lots`), and each lot gets a
building made by a split grammar after Mueller et al. (2006) (:mod:`procgen.city.cga`):
a rectangular mass set back from the lot's street side, floors, facade tiles, windows,
doors, ledges and a roof. Dense places get the ``tall_rules`` (offices by default), the
rest the ``rules`` (houses). Heights follow the population map.

The scene is in metres, Z up, the ground at z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import Polygon

from core.config import Config, option
from procgen.city.cga import LABELS, build, load_grammar
from procgen.city.lots import land_near_roads, road_area, subdivide_lots
from procgen.city.roads import PATTERNS, CityMaps, city_maps, grow_roads

__all__ = ["CityConfig", "City", "Building", "generate_city", "overlaps", "HIGHWAY_HALF_WIDTH",
           "STREET_HALF_WIDTH", "ELEMENTS"]


HIGHWAY_HALF_WIDTH = 6.0  # metres: road ribbons, highways wider than streets
STREET_HALF_WIDTH = 3.5
ELEMENTS = (*LABELS, "street", "highway")
"""Element codes of the city's triangles: the building labels, then the roads."""


@dataclass
class CityConfig(Config):
    """City parameters (metres, degrees): the options of ``scanamp procgen city``."""

    size: float = option(2000.0, unit="m", range="[100, inf)", help="side of the square map")
    pattern: str = option("organic", choices=PATTERNS,
                          help="street pattern of the global goals (Parish and Mueller): "
                               "grid, radial, organic, or elevation (least climb)")
    centres: int = option(3, range="[1, 50]", help="population centres")
    highway_length: float = option(120.0, unit="m", range="(0, inf)",
                                   help="length of a highway segment")
    street_length: float = option(70.0, unit="m", range="(0, inf)",
                                  help="length of a street segment")
    snap_radius: float = option(25.0, unit="m", range="[0, inf)",
                                help="road ends this close to an intersection join it")
    highway_fan: float = option(30.0, unit="deg", range="[0, 180]",
                                help="spread of the directions a highway samples")
    grid_angle: float = option(0.0, unit="deg", range="[-90, 90]",
                               help="orientation of the grid pattern's axes from east")
    organic_wander: float = option(14.0, unit="deg", range="[0, 90]",
                                   help="organic pattern: how far a street turns per segment "
                                        "(standard deviation)")
    organic_branch_spread: float = option(25.0, unit="deg", range="[0, 90]",
                                          help="organic pattern: spread of branch angles "
                                               "about the right angle")
    relief: float = option(60.0, unit="m", range="[0, inf)",
                           help="height of the hills of the generated elevation map")
    max_slope: float = option(15.0, unit="deg", range="(0, 90)",
                              help="roads steeper than this are rejected")
    max_segments: int = option(600, range="[1, 100000]", help="road segments at most")
    river_width: float = option(120.0, unit="m", range="[0, inf)", help="river width (0: none)")
    parks: int = option(2, range="[0, 100]", help="parks (no roads, no buildings)")
    park_radius: float = option(120.0, unit="m", range="(0, inf)", help="park radius")
    lot_depth: float = option(26.0, unit="m", range="(0, inf)",
                              help="depth of the land along a road that is cut into lots")
    lot_width: float = option(20.0, unit="m", range="(0, inf)",
                              help="lots are cut until no larger than lot_width x lot_depth")
    min_frontage: float = option(6.0, unit="m", range="(0, inf)",
                                 help="a lot shares at least this much boundary with a road")
    setback: float = option(2.0, unit="m", range="[0, inf)",
                            help="buildings stand this far inside their lot's boundary")
    max_floors: int = option(24, range="[1, 200]", help="floors of the tallest building")
    rules: str = option("residential", help="split grammar of the buildings: a shipped rule "
                                            "file (residential, office) or a .toml path")
    tall_rules: str = option("office", help="split grammar of buildings of more than "
                                            "tall_floors floors")
    tall_floors: int = option(5, range="[1, 200]",
                              help="buildings with more floors use tall_rules")
    tree_species: str = option("", help="Weber & Penn species planted along the streets and "
                                        "in the parks, comma-separated (shipped names or "
                                        ".toml files; empty: no trees)")
    tree_spacing: float = option(12.0, unit="m", range="(0, inf)",
                                 help="distance between street trees along a verge")
    park_trees: float = option(40.0, unit="1/ha", range="[0, 10000]",
                               help="trees per hectare of park (with tree_species)")


@dataclass
class Building:
    """One building: its rectangular ``footprint (4, 2)`` (first edge along the street,
    counter-clockwise), eave and ridge heights (metres), floors, roof kind and pitch
    (degrees), the lot it stands on, the grammar that made it, and its windows and doors
    per facade (``front``, ``back``, ``left``, ``right``)."""

    footprint: np.ndarray
    height: float
    ridge: float
    floors: int
    roof: str
    pitch: float
    lot: int
    rules: str
    windows: dict
    doors: dict


@dataclass
class City:
    """A generated city.

    Attributes
    ----------
    nodes : (k, 2) float64
        Road intersections, bends and ends.
    edges : (e, 2) int64
        Road segments as node index pairs.
    highway : (e,) bool
    lots : list of procgen.city.lots.Lot
    buildings : list of Building
    footprints : (b, 4) float64
        ``cx, cy, half_x, half_y`` of each building in its frame (``lot_frames``).
    lot_frames : (b, 2) float64
        Angle (radians) of each building's street side from +x, and 0.
    vertices, triangles : arrays
        All buildings and flat road ribbons as one mesh.
    part : (n,) int8
        What each vertex belongs to: 0 a building, 1 a street, 2 a highway.
    owner : (n,) int64
        Index of the building (in ``buildings``) or road (in ``edges``) of each vertex.
    element : (t,) int8
        What each triangle is, an index in :data:`ELEMENTS` (wall, window, door, ledge,
        roof, ground, street, highway).
    heights : (b,) float64
        Height of each building's top (its ridge), metres.
    maps : procgen.city.roads.CityMaps
    trees : procgen.city.trees.CityTrees or None
        Street and park trees (``config.tree_species``), instanced.
    """

    config: CityConfig
    nodes: np.ndarray
    edges: np.ndarray
    highway: np.ndarray
    lots: list = field(default_factory=list)
    buildings: list = field(default_factory=list)
    footprints: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))
    lot_frames: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    vertices: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    triangles: np.ndarray = field(default_factory=lambda: np.empty((0, 3), np.int64))
    part: np.ndarray = field(default_factory=lambda: np.empty(0, np.int8))
    owner: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    element: np.ndarray = field(default_factory=lambda: np.empty(0, np.int8))
    heights: np.ndarray = field(default_factory=lambda: np.empty(0))
    maps: CityMaps | None = None
    trees: object = None

    @property
    def density(self):
        return self.maps.density

    @property
    def water(self):
        return self.maps.water

    @property
    def park(self):
        return self.maps.park

    def half_widths(self) -> np.ndarray:
        """Half width of each road segment, metres."""
        return np.where(self.highway, HIGHWAY_HALF_WIDTH, STREET_HALF_WIDTH)


def _footprint(lot, setback: float) -> np.ndarray | None:
    """The largest rectangle, aligned with the lot's street side, inside the lot less the
    setback: ``(4, 2)`` corners, first edge along the street, or None."""
    inner = lot.polygon.buffer(-setback, join_style="mitre")
    if inner.is_empty or inner.area < 16.0:
        return None
    if inner.geom_type != "Polygon":
        inner = max(inner.geoms, key=lambda g: g.area)
    u = lot.front[1] - lot.front[0]
    u = u / max(np.hypot(*u), 1e-12)
    v = -lot.front_normal                       # into the lot, away from the street
    if u[0] * v[1] - u[1] * v[0] < 0:           # keep (u, v) counter-clockwise
        u = -u
    u = np.array([v[1], -v[0]])                 # exactly perpendicular
    pts = np.asarray(inner.exterior.coords)
    c = pts.mean(0)
    a, b = (pts - c) @ u, (pts - c) @ v
    lo, hi = np.array([a.min(), b.min()]), np.array([a.max(), b.max()])
    mid = 0.5 * (lo + hi)
    for _ in range(14):
        corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        rect = c + corners[:, :1] * u + corners[:, 1:] * v
        if inner.contains(Polygon(rect)):
            if np.min(hi - lo) < 4.0:
                return None
            return rect
        lo, hi = mid + 0.88 * (lo - mid), mid + 0.88 * (hi - mid)
    return None


def generate_city(rng: np.random.Generator, config: CityConfig | None = None, *,
                  maps: CityMaps | None = None) -> City:
    """Grow roads, cut lots and build a building on each.

    Parameters
    ----------
    rng : numpy.random.Generator
    config : CityConfig, optional
    maps : procgen.city.roads.CityMaps, optional
        The maps to grow on (:func:`procgen.city.roads.city_maps` with the user's rasters);
        by default drawn from ``rng``.

    Returns
    -------
    City
    """
    cfg = config or CityConfig()
    grammars = {name: load_grammar(name) for name in {cfg.rules, cfg.tall_rules}}
    maps = maps or city_maps(cfg, rng)
    nodes, edges, highway = grow_roads(cfg, rng, maps)
    city = City(cfg, nodes, edges, highway, maps=maps)
    if len(edges) == 0:
        return city
    half_w = city.half_widths()
    roads = road_area(nodes, edges, half_w)
    land = land_near_roads(cfg.size, roads, depth=cfg.lot_depth, water_mask=maps.water,
                           park_mask=maps.park)
    axes = np.stack([nodes[edges[:, 0]], nodes[edges[:, 1]]], 1)
    lots = subdivide_lots(land, roads, list(axes), lot_area=cfg.lot_width * cfg.lot_depth,
                          min_area=0.25 * cfg.lot_width * cfg.lot_depth,
                          min_frontage=cfg.min_frontage, rng=rng)
    city.lots = lots
    centroids = np.array([lot.polygon.centroid.coords[0] for lot in lots]).reshape(-1, 2)
    dens = maps.density(centroids) if len(lots) else np.empty(0)
    peak = max(float(dens.max()), 1e-12) if len(dens) else 1.0
    buildings, vs, fs, els, owners = [], [], [], [], []
    count = 0
    for i, lot in enumerate(lots):
        fp = _footprint(lot, cfg.setback)
        if fp is None:
            continue
        rel = float(dens[i]) / peak
        floors = int(np.clip(np.round(1 + (cfg.max_floors - 1) * rel**2
                                      * rng.uniform(0.5, 1.0)), 1, cfg.max_floors))
        depth = float(np.linalg.norm(fp[3] - fp[0]))
        width = float(np.linalg.norm(fp[1] - fp[0]))
        floors = min(floors, max(int(3 * min(width, depth) / 3.0), 1))   # slender at most 3:1
        name = cfg.tall_rules if floors > cfg.tall_floors else cfg.rules
        geo = build(grammars[name], fp, floors=floors, rng=rng)
        v, f, lab = geo.mesh()
        k = len(buildings)
        buildings.append(Building(fp, geo.eave_height, geo.ridge_height, floors, geo.roof_kind,
                                  float(np.degrees(np.arctan2(geo.ridge_height - geo.eave_height,
                                                              0.5 * min(width, depth))))
                                  if geo.roof_kind != "flat" else 0.0, i, name,
                                  geo.windows, geo.doors))
        vs.append(v)
        fs.append(f + count)
        els.append(lab)
        owners.append(np.full(len(v), k, np.int64))
        count += len(v)
    city.buildings = buildings
    city.heights = np.array([b.ridge for b in buildings])
    fps, frames = [], []
    for b in buildings:
        u = b.footprint[1] - b.footprint[0]
        w = b.footprint[3] - b.footprint[0]
        fps.append([*b.footprint.mean(0), 0.5 * np.hypot(*u), 0.5 * np.hypot(*w)])
        frames.append([np.arctan2(u[1], u[0]), 0.0])
    city.footprints = np.array(fps).reshape(-1, 4)
    city.lot_frames = np.array(frames).reshape(-1, 2)
    parts = [np.zeros(count, np.int8)]
    for e, ((i, j), hw) in enumerate(zip(edges, highway, strict=True)):
        p, q = nodes[i], nodes[j]
        d = q - p
        n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-12) * half_w[e]
        vs.append(np.array([[*(p - n), 0.05], [*(q - n), 0.05], [*(q + n), 0.05],
                            [*(p + n), 0.05]]))
        fs.append(np.array([[0, 1, 2], [0, 2, 3]]) + count)
        els.append(np.full(2, ELEMENTS.index("highway" if hw else "street"), np.int8))
        owners.append(np.full(4, e, np.int64))
        parts.append(np.full(4, 2 if hw else 1, np.int8))
        count += 4
    city.part = np.concatenate(parts)
    city.owner = np.concatenate(owners)
    city.vertices = np.vstack(vs)
    city.triangles = np.vstack(fs).astype(np.int64)
    city.element = np.concatenate(els)
    if cfg.tree_species:   # drawn last: a city without trees is the city of before
        from procgen.city.trees import city_trees

        city.trees = city_trees(city, rng=rng, species=[s.strip() for s in
                                                         cfg.tree_species.split(",")
                                                         if s.strip()],
                                spacing=cfg.tree_spacing, park_density=cfg.park_trees)
    return city


def footprint_polygons(city: City) -> list:
    """The buildings' footprints as shapely polygons."""
    return [Polygon(b.footprint) for b in city.buildings]


def overlaps(city: City) -> dict:
    """Areas (m^2) where the city breaks its own rules: buildings over roads, buildings over
    each other, roads in water (sampled every metre); 0 everywhere for a valid city."""
    roads = road_area(city.nodes, city.edges, city.half_widths())
    fps = footprint_polygons(city)
    tree = shapely.STRtree(fps)
    pairs = tree.query(fps, predicate="intersects")
    b_b = sum(fps[i].intersection(fps[j]).area for i, j in pairs.T if i < j)
    b_r = sum(p.intersection(roads).area for p in fps)
    a, b = city.nodes[city.edges[:, 0]], city.nodes[city.edges[:, 1]]
    wet = 0.0
    for p, q in zip(a, b, strict=True):
        n = max(int(np.linalg.norm(q - p)), 2)
        s = p + np.linspace(0, 1, n)[:, None] * (q - p)
        wet += float(city.maps.water(s).sum())
    return {"building_building_m2": float(b_b), "building_road_m2": float(b_r),
            "road_in_water_m": wet}
