"""Road networks grown as Parish and Mueller grow them: global goals and local constraints.

Parish and Mueller (2001), "Procedural modeling of cities", SIGGRAPH
(doi:10.1145/383259.383292) grow roads with an extended L-system whose modules are road
segments proposed with a delay (a priority queue). **Global goals** propose where a road
goes next: highways seek population, streets fill the space between them, and a *pattern*
shapes both:

- ``grid`` (New York, Chicago): every road runs along one of two orthogonal axes, with
  blocks of a set length;
- ``radial`` (Paris): roads run along the spokes out of the centre or around it, on rings;
- ``organic`` (old towns): each segment turns a little from the last, and branches leave at
  irregular angles;
- ``elevation`` (San Francisco's hills): of a fan of directions, a road takes the one with
  the least climb, so that roads follow the contour lines; highways trade population
  against climb.

**Local constraints** then adjust or reject each proposal against the maps: a segment
reaching water is shortened (roads never run in water), parks and slopes steeper than the
bound reject it, an end near an intersection snaps onto it, a crossing ends the segment at
a new intersection, and an end close to a road is extended onto it. Growth stops at
``max_segments``; a last pass joins dead ends to a road within reach and prunes short
stubs, as the constraints of the paper would have done had the road grown further.

Maps are functions of plan positions ``(n, 2)`` in metres over the square
``[-size / 2, size / 2]^2``; :func:`city_maps` makes them from the seed or from rasters the
user gives (population, water, elevation).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from core.validate import InputError, check_choice

__all__ = ["PATTERNS", "CityMaps", "city_maps", "grow_roads", "segments_cross",
           "point_segment_distance", "raster_sampler"]

PATTERNS = ("grid", "radial", "organic", "elevation")


@dataclass
class CityMaps:
    """The maps a city grows on: each a function of ``p (n, 2)`` metres.

    ``density`` is the population (any positive scale), ``water`` and ``park`` are masks,
    ``elevation`` is the ground height in metres. ``centre`` is the densest place, the
    centre of a radial town.
    """

    size: float
    density: object
    water: object
    park: object
    elevation: object
    centre: np.ndarray


def raster_sampler(grid: np.ndarray, size: float):
    """Bilinear sampling of a raster covering ``[-size/2, size/2]^2`` (row 0 at +y, north
    up, as an image or a GeoTIFF is stored); positions outside clamp to the border."""
    g = np.asarray(grid, np.float64)
    rows, cols = g.shape

    def sample(p):
        p = np.atleast_2d(np.asarray(p, np.float64))
        c = np.clip((p[:, 0] / size + 0.5) * (cols - 1), 0, cols - 1)
        r = np.clip((0.5 - p[:, 1] / size) * (rows - 1), 0, rows - 1)
        c0 = np.minimum(np.floor(c).astype(int), cols - 2) if cols > 1 else np.zeros(len(c), int)
        r0 = np.minimum(np.floor(r).astype(int), rows - 2) if rows > 1 else np.zeros(len(r), int)
        fc, fr = c - c0, r - r0
        c1, r1 = np.minimum(c0 + 1, cols - 1), np.minimum(r0 + 1, rows - 1)
        return ((1 - fr) * ((1 - fc) * g[r0, c0] + fc * g[r0, c1])
                + fr * ((1 - fc) * g[r1, c0] + fc * g[r1, c1]))

    return sample


def _check_rasters(rasters: dict) -> None:
    """Every raster given is a square 2-D grid of finite numbers, and all share one shape."""
    shape, first = None, None
    for name, (grid, path) in rasters.items():
        if grid is None:
            continue
        g = np.asarray(grid)
        if g.ndim != 2 or g.shape[0] != g.shape[1] or g.shape[0] < 4:
            raise InputError(f"expected a square map of at least 4 x 4 cells covering the "
                             f"city, got shape {g.shape}", path=path, field=name)
        if not np.all(np.isfinite(g.astype(np.float64))):
            raise InputError("expected finite values", path=path, field=name)
        if shape is not None and g.shape != shape:
            raise InputError(f"expected the shape of the {first} map {shape}, got {g.shape}",
                             path=path, field=name)
        shape, first = g.shape, first or name


def city_maps(cfg, rng: np.random.Generator, *, population=None, water=None,
              elevation=None, paths: dict | None = None) -> CityMaps:
    """The maps of ``cfg`` (a :class:`procgen.city.CityConfig`).

    Population centres, a river, parks and hills are drawn from ``rng`` unless a raster is
    given for them (``population``, ``water`` (non-zero is water), ``elevation`` in metres:
    square 2-D arrays over the map, north up, all of one shape). ``paths`` names the
    files the rasters came from, for error messages.
    """
    paths = paths or {}
    _check_rasters({"population": (population, paths.get("population")),
                    "water": (water, paths.get("water")),
                    "elevation": (elevation, paths.get("elevation"))})
    half = cfg.size / 2
    centres = rng.uniform(-0.6 * half, 0.6 * half, size=(cfg.centres, 2))
    sigma = rng.uniform(0.2, 0.35, size=cfg.centres) * cfg.size
    if population is not None:
        if np.any(np.asarray(population) < 0):
            raise InputError("expected population >= 0", path=paths.get("population"),
                             field="population")
        density = raster_sampler(population, cfg.size)
    else:
        def density(p):
            p = np.atleast_2d(p)
            d2 = ((p[:, None, :] - centres[None]) ** 2).sum(-1)
            return np.exp(-d2 / (2 * sigma**2)).sum(-1)

    a, w, b = rng.uniform(50, 150), rng.uniform(250, 500), rng.uniform(-0.6, 0.6) * half
    if water is not None:
        wet = raster_sampler(np.asarray(water, np.float64) != 0, cfg.size)

        def water_fn(p):
            return wet(p) > 0.5
    else:
        def water_fn(p):
            p = np.atleast_2d(p)
            return np.abs(p[:, 1] - (a * np.sin(p[:, 0] / w) + b)) < cfg.river_width / 2

    parks = rng.uniform(-0.7 * half, 0.7 * half, size=(cfg.parks, 2))

    def park(p):
        p = np.atleast_2d(p)
        if len(parks) == 0:
            return np.zeros(len(p), bool)
        return (((p[:, None, :] - parks[None]) ** 2).sum(-1) < cfg.park_radius**2).any(-1)

    hills = rng.uniform(-half, half, size=(6, 2))
    hill_h = rng.uniform(0.3, 1.0, size=6) * cfg.relief
    hill_s = rng.uniform(0.12, 0.3, size=6) * cfg.size
    if elevation is not None:
        elev = raster_sampler(elevation, cfg.size)
    else:
        def elev(p):
            p = np.atleast_2d(p)
            d2 = ((p[:, None, :] - hills[None]) ** 2).sum(-1)
            return (hill_h * np.exp(-d2 / (2 * hill_s**2))).sum(-1)

    # the densest place on land: a radial town's centre
    probe = np.stack(np.meshgrid(np.linspace(-0.6 * half, 0.6 * half, 25),
                                 np.linspace(-0.6 * half, 0.6 * half, 25)), -1).reshape(-1, 2)
    ring = 0.5 * cfg.highway_length * np.stack(
        [np.cos(np.arange(8) * np.pi / 4), np.sin(np.arange(8) * np.pi / 4)], 1)
    around = (probe[:, None, :] + ring[None]).reshape(-1, 2)
    clear = ~(water_fn(around) | park(around)).reshape(len(probe), 8).any(1)
    land = ~water_fn(probe) & ~park(probe)
    probe = probe[land & clear] if np.any(land & clear) else probe[land]
    if len(probe) == 0:
        raise InputError("the whole map is water or park: no land to build a city on",
                         path=paths.get("water"), field="water")
    centre = probe[np.argmax(density(probe))]
    return CityMaps(cfg.size, density, water_fn, park, elev, centre)


def segments_cross(p, q, a, b):
    """For one segment ``p -> q`` against many ``a (m, 2) -> b (m, 2)``: the parameter ``t``
    along ``p -> q`` of a proper crossing (NaN where none)."""
    r = q - p
    s = b - a
    den = r[0] * s[:, 1] - r[1] * s[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((a[:, 0] - p[0]) * s[:, 1] - (a[:, 1] - p[1]) * s[:, 0]) / den
        u = ((a[:, 0] - p[0]) * r[1] - (a[:, 1] - p[1]) * r[0]) / den
    ok = (np.abs(den) > 1e-12) & (t > 1e-9) & (t < 1 - 1e-9) & (u > 1e-9) & (u < 1 - 1e-9)
    return np.where(ok, t, np.nan)


def point_segment_distance(p, a, b):
    """Distance of the point ``p (2,)`` to segments ``a (m, 2) -> b (m, 2)`` and the
    parameter of the nearest point on each: ``(dist (m,), t (m,))``."""
    ab = b - a
    L2 = np.maximum((ab**2).sum(-1), 1e-12)
    t = np.clip(((p - a) * ab).sum(-1) / L2, 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=-1), t


def _direction(a: float) -> np.ndarray:
    return np.array([np.cos(a), np.sin(a)])


class _Network:
    """The growing graph: nodes, edges and the local constraints that insert segments."""

    def __init__(self, cfg, maps: CityMaps):
        self.cfg, self.maps = cfg, maps
        self.nodes: list[np.ndarray] = []
        self.edges: list[tuple[int, int]] = []
        self.highway: list[bool] = []
        self.max_grade = np.tan(np.radians(cfg.max_slope))

    def add_node(self, p) -> int:
        self.nodes.append(np.asarray(p, np.float64))
        return len(self.nodes) - 1

    def split_edge(self, k: int, x) -> int:
        a, b = self.edges[k]
        mid = self.add_node(x)
        self.edges[k] = (a, mid)
        self.edges.append((mid, b))
        self.highway.append(self.highway[k])
        return mid

    def on_land(self, p, q) -> bool:
        samples = p + np.linspace(0, 1, 9)[1:, None] * (q - p)
        m = self.maps
        if m.water(samples).any() or m.park(samples).any():
            return False
        if np.abs(samples).max() > self.cfg.size / 2:
            return False
        z = m.elevation(np.vstack([p[None], samples]))
        run = np.linalg.norm(q - p) / len(samples)
        return bool(np.all(np.abs(np.diff(z)) <= self.max_grade * run + 1e-9))

    def insert(self, src: int, q: np.ndarray, is_hw: bool):
        """Apply the local constraints to the proposal ``src -> q``; returns the new end
        node and whether it is free (the road may keep growing from it), or None."""
        cfg = self.cfg
        p = self.nodes[src]
        ok = False
        for scale in (1.0, 0.75, 0.5):       # water, parks, slopes: shorten, else reject
            qq = p + scale * (q - p)
            if self.on_land(p, qq):
                q, ok = qq, True
                break
        if not ok:
            return None
        if not self.edges:
            new = self.add_node(q)
            self.edges.append((src, new))
            self.highway.append(is_hw)
            return new, True
        E = np.array(self.edges)
        N = np.array(self.nodes)
        t = segments_cross(p, q, N[E[:, 0]], N[E[:, 1]])
        if np.any(np.isfinite(t)):           # a crossing: end at a new intersection
            k = int(np.nanargmin(t))
            x = p + t[k] * (q - p)
            if np.linalg.norm(N - x, axis=1).min() < 0.3 * cfg.snap_radius:
                return None
            end = self.split_edge(k, x)
            self.edges.append((src, end))
            self.highway.append(is_hw)
            return end, False
        dist = np.linalg.norm(N - q, axis=1)
        dist[src] = np.inf
        j = int(np.argmin(dist))
        if dist[j] < cfg.snap_radius:        # snap onto a nearby intersection
            if (src, j) in self.edges or (j, src) in self.edges:
                return None
            if np.any(np.isfinite(segments_cross(p, N[j], N[E[:, 0]], N[E[:, 1]]))):
                return None
            if not self.on_land(p, N[j]):
                return None
            self.edges.append((src, j))
            self.highway.append(is_hw)
            return j, False
        ds, ts = point_segment_distance(q, N[E[:, 0]], N[E[:, 1]])
        ds[(E == src).any(1)] = np.inf
        k = int(np.argmin(ds))
        if ds[k] < 0.5 * cfg.snap_radius and 0.05 < ts[k] < 0.95:   # extend onto a road
            a, b = E[k]
            x = N[a] + ts[k] * (N[b] - N[a])
            if (not np.any(np.isfinite(segments_cross(p, x, N[E[:, 0]], N[E[:, 1]])))
                    and np.linalg.norm(N - x, axis=1).min() >= 0.3 * cfg.snap_radius
                    and self.on_land(p, x)):
                end = self.split_edge(k, x)
                self.edges.append((src, end))
                self.highway.append(is_hw)
                return end, False
        new = self.add_node(q)
        self.edges.append((src, new))
        self.highway.append(is_hw)
        return new, True


def _goal(pattern: str, p, ang: float, is_hw: bool, cfg, maps: CityMaps, rng,
          grid_angle: float) -> float:
    """The global goal: the direction a road leaving ``p`` heading ``ang`` takes next."""
    length = cfg.highway_length if is_hw else cfg.street_length
    if pattern == "grid":
        k = np.round((ang - grid_angle) / (np.pi / 2))
        return grid_angle + k * np.pi / 2
    if pattern == "radial":
        r = p - maps.centre
        if np.hypot(*r) < 1e-6:
            return ang
        radial = np.arctan2(r[1], r[0])
        options = radial + np.arange(4) * np.pi / 2
        diff = np.abs(np.angle(np.exp(1j * (options - ang))))
        return float(options[int(np.argmin(diff))])
    fan = np.radians(cfg.highway_fan if is_hw else 25.0)
    tries = ang + np.linspace(-fan, fan, 7)
    ends = p + length * np.stack([np.cos(tries), np.sin(tries)], 1)
    if pattern == "organic":
        if is_hw:
            return float(tries[int(np.argmax(maps.density(ends)))])
        return float(ang + rng.normal(0.0, np.radians(cfg.organic_wander)))
    # elevation: the least climb, highways trading population against it
    climb = np.abs(maps.elevation(ends) - maps.elevation(p[None])[0]) / length
    if is_hw:
        dens = maps.density(ends)
        score = dens / max(float(dens.max()), 1e-12) - 4.0 * climb
        return float(tries[int(np.argmax(score))])
    return float(tries[int(np.argmin(climb + 1e-3 * rng.random(len(tries))))])


def _branch_angle(pattern: str, rng, cfg) -> float:
    if pattern == "organic":
        return np.pi / 2 + rng.normal(0.0, np.radians(cfg.organic_branch_spread))
    return np.pi / 2


def grow_roads(cfg, rng: np.random.Generator, maps: CityMaps):
    """Grow the road network of ``cfg`` (a :class:`procgen.city.CityConfig`) on ``maps``.

    Returns
    -------
    nodes : (k, 2) float64
        Intersections, bends and ends, metres.
    edges : (e, 2) int64
        Segments as node index pairs; the network is planar (segments meet only at nodes).
    highway : (e,) bool
    """
    pattern = check_choice(cfg.pattern, "pattern", PATTERNS)
    net = _Network(cfg, maps)
    grid_angle = float(np.radians(cfg.grid_angle))
    start = maps.centre
    root = net.add_node(start)
    peak = max(float(maps.density(start[None])[0]), 1e-12)
    queue: list = []
    counter = 0
    ang0 = grid_angle if pattern == "grid" else float(rng.uniform(0, 2 * np.pi))
    for k in range(4):                   # highways leave the centre every way
        heapq.heappush(queue, (0.0, counter, root, ang0 + k * np.pi / 2, True))
        counter += 1
    while queue and len(net.edges) < cfg.max_segments:
        delay, _, src, ang, is_hw = heapq.heappop(queue)
        p = net.nodes[src]
        ang = _goal(pattern, p, ang, is_hw, cfg, maps, rng, grid_angle)
        length = cfg.highway_length if is_hw else cfg.street_length
        got = net.insert(src, p + length * _direction(ang), is_hw)
        if got is None:
            continue
        new, free = got
        if not free:
            continue
        dens = float(maps.density(net.nodes[new][None])[0]) / peak
        if is_hw:
            heapq.heappush(queue, (delay + 1, counter, new, ang, True))
            counter += 1
            if rng.random() < 0.12 + 0.2 * dens:
                side = rng.choice([-1, 1])
                heapq.heappush(queue, (delay + 1, counter, new,
                                       ang + side * _branch_angle(pattern, rng, cfg), True))
                counter += 1
        elif rng.random() < 0.55 + 0.45 * dens:
            heapq.heappush(queue, (delay + 3, counter, new, ang, False))
            counter += 1
        for side in (-1, 1):       # streets branch off where people live
            if rng.random() < 0.65 * min(dens + 0.25, 1.0):
                heapq.heappush(queue, (delay + 5, counter, new,
                                       ang + side * _branch_angle(pattern, rng, cfg), False))
                counter += 1
    _join_dead_ends(net)
    nodes, edges, highway = _prune_stubs(net, 0.5 * cfg.street_length)
    return nodes, edges, highway


def _join_dead_ends(net: _Network) -> None:
    """A dead end within 1.5 street lengths of a road, straight ahead, is extended onto it
    (the "extend to nearby roads" constraint, with the reach of a road grown further)."""
    cfg = net.cfg
    reach = 1.5 * cfg.street_length
    for _ in range(2):
        if not net.edges:
            return
        E = np.array(net.edges)
        deg = np.bincount(E.ravel(), minlength=len(net.nodes))
        for v in np.flatnonzero(deg == 1):
            E = np.array(net.edges)
            k = int(np.flatnonzero((E == v).any(1))[0])
            u = E[k, 0] if E[k, 1] == v else E[k, 1]
            p = net.nodes[v]
            d = p - net.nodes[u]
            d = d / max(np.linalg.norm(d), 1e-12)
            N = np.array(net.nodes)
            a, b = N[E[:, 0]], N[E[:, 1]]
            t = segments_cross(p, p + reach * d, a, b)
            t[(E == v).any(1)] = np.nan
            if not np.any(np.isfinite(t)):
                continue
            j = int(np.nanargmin(t))
            x = p + t[j] * reach * d
            if not net.on_land(p, x):
                continue
            near = np.linalg.norm(N - x, axis=1)
            near[v] = np.inf
            w = int(np.argmin(near))
            if near[w] < 0.3 * cfg.snap_radius:
                if w in E[j] and not ((v, w) in net.edges or (w, v) in net.edges):
                    net.edges.append((v, w))
                    net.highway.append(net.highway[k])
                continue
            end = net.split_edge(j, x)
            net.edges.append((v, end))
            net.highway.append(net.highway[k])


def _prune_stubs(net: _Network, min_length: float):
    """Drop dead-end segments shorter than ``min_length`` (repeatedly) and unused nodes."""
    nodes = np.array(net.nodes)
    edges = np.array(net.edges, np.int64).reshape(-1, 2)
    highway = np.array(net.highway, bool)
    while len(edges):
        deg = np.bincount(edges.ravel(), minlength=len(nodes))
        length = np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
        stub = (deg[edges].min(1) == 1) & (length < min_length) & ~highway
        if not stub.any():
            break
        edges, highway = edges[~stub], highway[~stub]
    used = np.unique(edges)
    remap = np.full(len(nodes), -1, np.int64)
    remap[used] = np.arange(len(used))
    return nodes[used], remap[edges], highway
