"""A procedural city: roads grown with global goals and local constraints, CSG buildings.

Roads follow Parish and Mueller (2001), "Procedural modeling of cities", SIGGRAPH
(doi:10.1145/383259.383292): an extended L-system whose modules are road segments
proposed with a delay (a priority queue). **Global goals** steer proposals: highways
sample a fan of directions and take the one with the most population along it, and
branch with a probability that grows with population; streets branch at right angles.
**Local constraints** then adjust or reject each proposal: a segment ending in water
is shortened (or rotated) to stay on land, parks reject it, an end point near an existing
intersection snaps to it, a crossing truncates the segment at a new intersection, and an
end close to an existing road is extended onto it.

Buildings stand on lots along the streets. Each is a constructive solid geometry tree of
simple solids (boxes and vertical cylinders; union, difference) evaluated as a signed
distance field and meshed with marching cubes (VTK through pyvista).

The scene is in metres, Z up, the ground at z = 0.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field

import numpy as np

from core.config import Config, option
from core.validate import check_range

__all__ = ["CityConfig", "City", "generate_city", "grow_roads", "Box", "Cylinder", "Union",
           "Difference", "csg_mesh", "segments_cross"]


HIGHWAY_HALF_WIDTH = 6.0  # metres: road ribbons, highways wider than streets
STREET_HALF_WIDTH = 3.5

# --------------------------------------------------------------------------- CSG


@dataclass(frozen=True)
class Box:
    """Axis-aligned box: ``center (3,)``, ``half (3,)`` half extents."""

    center: tuple
    half: tuple

    def sdf(self, p):
        q = np.abs(p - np.asarray(self.center)) - np.asarray(self.half)
        return (np.linalg.norm(np.maximum(q, 0), axis=-1)
                + np.minimum(np.max(q, axis=-1), 0))

    def bounds(self):
        c, h = np.asarray(self.center), np.asarray(self.half)
        return c - h, c + h


@dataclass(frozen=True)
class Cylinder:
    """Vertical cylinder: ``center (3,)`` of its axis, ``radius``, ``half_height``."""

    center: tuple
    radius: float
    half_height: float

    def sdf(self, p):
        d = p - np.asarray(self.center)
        q = np.stack([np.hypot(d[..., 0], d[..., 1]) - self.radius,
                      np.abs(d[..., 2]) - self.half_height], -1)
        return (np.linalg.norm(np.maximum(q, 0), axis=-1)
                + np.minimum(np.max(q, axis=-1), 0))

    def bounds(self):
        c = np.asarray(self.center)
        h = np.array([self.radius, self.radius, self.half_height])
        return c - h, c + h


@dataclass(frozen=True)
class Union:
    parts: tuple

    def sdf(self, p):
        return np.min([s.sdf(p) for s in self.parts], axis=0)

    def bounds(self):
        b = [s.bounds() for s in self.parts]
        return np.min([x[0] for x in b], axis=0), np.max([x[1] for x in b], axis=0)


@dataclass(frozen=True)
class Difference:
    a: object
    b: object

    def sdf(self, p):
        return np.maximum(self.a.sdf(p), -self.b.sdf(p))

    def bounds(self):
        return self.a.bounds()


def csg_mesh(solid, *, voxel: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Mesh a CSG tree: sample its signed distance on a grid, marching cubes at 0.

    Returns ``(vertices (k, 3) float64, triangles (t, 3) int64)``, outward oriented.
    """
    import pyvista as pv

    lo, hi = solid.bounds()
    lo = lo - 2 * voxel
    hi = hi + 2 * voxel
    dims = np.ceil((hi - lo) / voxel).astype(int) + 1
    grid = pv.ImageData(dimensions=tuple(dims), spacing=(voxel,) * 3, origin=tuple(lo))
    pts = np.asarray(grid.points)
    grid.point_data["d"] = solid.sdf(pts)
    surf = grid.contour([0.0], scalars="d").triangulate().clean()
    v = np.asarray(surf.points, np.float64)
    f = np.asarray(surf.faces).reshape(-1, 4)[:, 1:].astype(np.int64)
    from procgen.sweeps import mesh_volume

    if len(f) and mesh_volume(v, f) < 0:
        f = f[:, ::-1].copy()
    return v, f


# --------------------------------------------------------------------------- maps


@dataclass
class CityConfig(Config):
    """City parameters (metres, degrees): the options of ``scanamp procgen city``."""

    size: float = option(2000.0, unit="m", range="[100, inf)", help="side of the square map")
    centres: int = option(3, range="[1, 50]", help="population centres")
    highway_length: float = option(120.0, unit="m", range="(0, inf)",
                                   help="length of a highway segment")
    street_length: float = option(70.0, unit="m", range="(0, inf)",
                                  help="length of a street segment")
    snap_radius: float = option(25.0, unit="m", range="[0, inf)",
                                help="road ends this close to an intersection join it")
    highway_fan: float = option(30.0, unit="deg", range="[0, 180]",
                                help="spread of the directions a highway samples")
    max_segments: int = option(600, range="[1, 100000]", help="road segments at most")
    river_width: float = option(120.0, unit="m", range="[0, inf)", help="river width (0: none)")
    parks: int = option(2, range="[0, 100]", help="parks (no roads, no buildings)")
    park_radius: float = option(120.0, unit="m", range="(0, inf)", help="park radius")
    lot_depth: float = option(22.0, unit="m", range="(0, inf)", help="lot depth from the road")
    lot_width: float = option(18.0, unit="m", range="(0, inf)", help="lot width along the road")
    road_clearance: float = option(6.0, unit="m", range="[0, inf)",
                                   help="lots start this far from the road's axis")
    voxel: float = option(1.5, unit="m", range="(0, inf)", help="building meshing voxel")


@dataclass
class City:
    """A generated city.

    Attributes
    ----------
    nodes : (k, 2) float64
        Road intersections and ends.
    edges : (e, 2) int64
        Road segments as node index pairs.
    highway : (e,) bool
    buildings : list
        CSG trees, one per building.
    footprints : (b, 4) float64
        ``cx, cy, half_x, half_y`` of each lot (axis-aligned in the lot's frame).
    vertices, triangles : arrays
        All buildings and flat road ribbons as one mesh.
    part : (n,) int8
        What each vertex belongs to: 0 a building, 1 a street, 2 a highway.
    owner : (n,) int64
        Index of the building (in ``buildings``) or road (in ``edges``) of each vertex.
    heights : (b,) float64
        Height of each building's top (its tallest solid), metres.
    """

    config: CityConfig
    nodes: np.ndarray
    edges: np.ndarray
    highway: np.ndarray
    buildings: list = field(default_factory=list)
    footprints: np.ndarray = field(default_factory=lambda: np.empty((0, 4)))
    lot_frames: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    vertices: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    triangles: np.ndarray = field(default_factory=lambda: np.empty((0, 3), np.int64))
    part: np.ndarray = field(default_factory=lambda: np.empty(0, np.int8))
    owner: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    heights: np.ndarray = field(default_factory=lambda: np.empty(0))
    density: object = None
    water: object = None
    park: object = None


def _maps(cfg: CityConfig, rng: np.random.Generator):
    half = cfg.size / 2
    centres = rng.uniform(-0.6 * half, 0.6 * half, size=(cfg.centres, 2))
    sigma = rng.uniform(0.2, 0.35, size=cfg.centres) * cfg.size

    def density(p):
        p = np.atleast_2d(p)
        d2 = ((p[:, None, :] - centres[None]) ** 2).sum(-1)
        return np.exp(-d2 / (2 * sigma**2)).sum(-1)

    # a river: a sinuous band crossing the map along y = a sin(x / w) + b
    a, w, b = rng.uniform(50, 150), rng.uniform(250, 500), rng.uniform(-0.6, 0.6) * half

    def water(p):
        p = np.atleast_2d(p)
        return np.abs(p[:, 1] - (a * np.sin(p[:, 0] / w) + b)) < cfg.river_width / 2

    parks = rng.uniform(-0.7 * half, 0.7 * half, size=(cfg.parks, 2))

    def park(p):
        p = np.atleast_2d(p)
        return (((p[:, None, :] - parks[None]) ** 2).sum(-1) < cfg.park_radius**2).any(-1)

    return density, water, park


# --------------------------------------------------------------------------- roads


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


def _point_segment_distance(p, a, b):
    ab = b - a
    L2 = np.maximum((ab**2).sum(-1), 1e-12)
    t = np.clip(((p - a) * ab).sum(-1) / L2, 0, 1)
    return np.linalg.norm(a + t[:, None] * ab - p, axis=-1), t


def grow_roads(cfg: CityConfig, rng: np.random.Generator, density, water, park):
    """Grow the road network; returns ``(nodes (k, 2), edges (e, 2), highway (e,))``."""
    half = cfg.size / 2
    nodes: list[np.ndarray] = []
    edges: list[tuple[int, int]] = []
    highway: list[bool] = []

    def add_node(p):
        nodes.append(np.asarray(p, np.float64))
        return len(nodes) - 1

    # start on land at the densest of a few samples
    cand = rng.uniform(-0.5 * half, 0.5 * half, size=(64, 2))
    cand = cand[~water(cand) & ~park(cand)]
    start = cand[np.argmax(density(cand))]
    root = add_node(start)
    queue: list = []
    counter = 0
    ang0 = rng.uniform(0, 2 * np.pi)
    for ang in (ang0, ang0 + np.pi):
        heapq.heappush(queue, (0.0, counter, root, ang, True))
        counter += 1
    fan = np.radians(cfg.highway_fan)
    while queue and len(edges) < cfg.max_segments:
        delay, _, src, ang, is_hw = heapq.heappop(queue)
        p = nodes[src]
        length = cfg.highway_length if is_hw else cfg.street_length
        if is_hw:  # global goal: follow population
            tries = ang + np.linspace(-fan, fan, 7)
            score = [density(p + length * np.array([np.cos(t), np.sin(t)]) * k).sum()
                     for t in tries for k in (1.0,)]
            ang = tries[int(np.argmax(score))]
        d = np.array([np.cos(ang), np.sin(ang)])
        q = p + length * d
        # local constraints: water -> shorten, else rotate; parks and map edge reject
        ok = False
        for scale in (1.0, 0.75, 0.5):
            qq = p + scale * length * d
            samples = p + np.linspace(0, 1, 8)[1:, None] * (qq - p)
            if not water(samples).any():
                q, ok = qq, True
                break
        if not ok or park(q)[0] or np.abs(q).max() > half:
            continue
        end = None
        if edges:
            E = np.array(edges)
            N = np.array(nodes)
            t = segments_cross(p, q, N[E[:, 0]], N[E[:, 1]])
            if np.any(np.isfinite(t)):  # crossing: truncate at the nearest intersection
                k = int(np.nanargmin(t))
                x = p + t[k] * (q - p)
                if np.linalg.norm(N - x, axis=1).min() < 0.3 * cfg.snap_radius:
                    continue  # too close to an intersection: drop the proposal
                a, b = E[k]
                mid = add_node(x)
                edges[k] = (a, mid)
                edges.append((mid, b))
                highway.append(highway[k])
                end = mid
            else:
                dist = np.linalg.norm(N - q, axis=1)
                dist[src] = np.inf
                j = int(np.argmin(dist))
                if dist[j] < cfg.snap_radius:  # snap to an intersection
                    if (src, j) in edges or (j, src) in edges:
                        continue
                    q2 = N[j]
                    t2 = segments_cross(p, q2, N[E[:, 0]], N[E[:, 1]])
                    if np.any(np.isfinite(t2)):
                        continue
                    end = j
                else:  # extend onto a nearby road
                    ds, ts = _point_segment_distance(q, N[E[:, 0]], N[E[:, 1]])
                    ds[(E == src).any(1)] = np.inf
                    k = int(np.argmin(ds))
                    if ds[k] < 0.5 * cfg.snap_radius and 0.05 < ts[k] < 0.95:
                        a, b = E[k]
                        x = N[a] + ts[k] * (N[b] - N[a])
                        if np.any(np.isfinite(segments_cross(p, x, N[E[:, 0]], N[E[:, 1]]))):
                            continue
                        if np.linalg.norm(N - x, axis=1).min() < 0.3 * cfg.snap_radius:
                            continue
                        mid = add_node(x)
                        edges[k] = (a, mid)
                        edges.append((mid, b))
                        highway.append(highway[k])
                        end = mid
        if end is not None:
            if end != src:
                edges.append((src, end))
                highway.append(is_hw)
            continue  # a road ending on another does not keep growing
        new = add_node(q)
        edges.append((src, new))
        highway.append(is_hw)
        # propose successors (the production of the road module)
        dens = float(density(q)[0]) / max(float(density(start)[0]), 1e-12)
        if is_hw:
            heapq.heappush(queue, (delay + 1, counter, new, ang, True))
            counter += 1
            if rng.random() < 0.15 + 0.2 * dens:
                side = rng.choice([-1, 1])
                heapq.heappush(queue, (delay + 1, counter, new, ang + side * np.pi / 2, True))
                counter += 1
        else:
            if rng.random() < 0.5 + 0.5 * dens:
                heapq.heappush(queue, (delay + 3, counter, new, ang, False))
                counter += 1
        for side in (-1, 1):  # streets branch at right angles where people live
            if rng.random() < 0.6 * min(dens + 0.2, 1.0):
                heapq.heappush(queue, (delay + 5, counter, new, ang + side * np.pi / 2, False))
                counter += 1
    return np.array(nodes), np.array(edges, np.int64).reshape(-1, 2), np.array(highway, bool)


# --------------------------------------------------------------------------- buildings


def _building(rng, cx, cy, hx, hy, height, angle):
    """A CSG tree in the lot frame, rotated about z by ``angle`` around (cx, cy) later."""
    base = Box((0.0, 0.0, height / 2), (hx, hy, height / 2))
    parts = [base]
    if height > 20 and rng.random() < 0.7:  # a set-back tower
        th = height * rng.uniform(0.3, 0.8)
        parts.append(Box((0.0, 0.0, height + th / 2), (0.6 * hx, 0.6 * hy, th / 2)))
        height += th
    if rng.random() < 0.4:  # a water tank on the roof
        parts.append(Cylinder((0.3 * hx, 0.3 * hy, height + 2.0), 0.25 * min(hx, hy), 2.0))
    solid = Union(tuple(parts))
    if rng.random() < 0.5:  # an arcade cut into the ground floor
        solid = Difference(solid, Box((0.0, -hy, 2.0), (0.7 * hx, 0.3 * hy, 2.5)))
    return solid


def _top(solid) -> float:
    """Highest z of a CSG tree (a difference is no higher than what it cuts)."""
    if isinstance(solid, Box):
        return float(solid.center[2] + solid.half[2])
    if isinstance(solid, Cylinder):
        return float(solid.center[2] + solid.half_height)
    if isinstance(solid, Union):
        return max(_top(s) for s in solid.parts)
    return _top(solid.a)


def generate_city(rng: np.random.Generator, config: CityConfig | None = None) -> City:
    """Grow roads, place lots and build CSG buildings.

    Parameters
    ----------
    rng : numpy.random.Generator
    config : CityConfig, optional

    Returns
    -------
    City
    """
    cfg = config or CityConfig()
    check_range(cfg.size, "size", 100, None)
    density, water, park = _maps(cfg, rng)
    nodes, edges, highway = grow_roads(cfg, rng, density, water, park)
    city = City(cfg, nodes, edges, highway, density=density, water=water, park=park)
    if len(edges) == 0:
        return city
    a, b = nodes[edges[:, 0]], nodes[edges[:, 1]]
    halfw = np.where(highway, HIGHWAY_HALF_WIDTH, STREET_HALF_WIDTH)
    peak = float(density(nodes).max())
    fps, frames, solids, heights = [], [], [], []
    centres = np.empty((0, 2))
    radii = np.empty(0)
    for (p, q) in zip(a, b, strict=True):
        d = q - p
        L = np.linalg.norm(d)
        if L < cfg.lot_width:
            continue
        d /= L
        n = np.array([-d[1], d[0]])
        for s in np.arange(cfg.lot_width, L - cfg.lot_width / 2, cfg.lot_width * 1.3):
            for side in (-1, 1):
                c = p + s * d + side * n * (cfg.road_clearance + cfg.lot_depth / 2)
                hx, hy = cfg.lot_width * 0.4, cfg.lot_depth * 0.4
                r = np.hypot(hx, hy)
                corners = c + np.array([[i * hx, j * hy] for i in (-1, 1) for j in (-1, 1)]) @ \
                    np.array([d, n])
                if water(corners).any() or park(corners).any() or water(c).any():
                    continue
                dist, _ = _point_segment_distance(c, a, b)
                if np.min(dist - halfw) < r + 1.0:  # a metre clear of every ribbon
                    continue
                if len(centres) and np.any(np.linalg.norm(centres - c, axis=1) < radii + r):
                    continue
                centres = np.vstack([centres, c])
                radii = np.append(radii, r)
                rel = float(density(c)[0]) / peak
                height = 6 + 80 * rel**2 * rng.uniform(0.5, 1.0)
                angle = np.arctan2(d[1], d[0])
                solids.append(_building(rng, 0.0, 0.0, hx, hy, height, angle))
                heights.append(_top(solids[-1]))
                fps.append([c[0], c[1], hx, hy])
                frames.append([angle, 0.0])
    city.buildings = solids
    city.heights = np.array(heights)
    city.footprints = np.array(fps).reshape(-1, 4)
    city.lot_frames = np.array(frames).reshape(-1, 2)
    vs, fs, owners = [], [], []
    count = 0
    for i, (solid, fp, fr) in enumerate(zip(solids, city.footprints, city.lot_frames,
                                            strict=True)):
        v, f = csg_mesh(solid, voxel=cfg.voxel)
        owners.append(np.full(len(v), i, np.int64))
        c, s = np.cos(fr[0]), np.sin(fr[0])
        v = v @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + [fp[0], fp[1], 0]
        vs.append(v)
        fs.append(f + count)
        count += len(v)
    # roads as flat ribbons slightly above the ground
    parts = [np.zeros(count, np.int8)]
    for e, ((p, q), hw) in enumerate(zip(zip(a, b, strict=True), highway, strict=True)):
        owners.append(np.full(4, e, np.int64))
        d = q - p
        n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-12) * (
            HIGHWAY_HALF_WIDTH if hw else STREET_HALF_WIDTH)
        quad = np.array([[*(p - n), 0.05], [*(q - n), 0.05], [*(q + n), 0.05],
                         [*(p + n), 0.05]])
        vs.append(quad)
        fs.append(np.array([[0, 1, 2], [0, 2, 3]]) + count)
        parts.append(np.full(4, 2 if hw else 1, np.int8))
        count += 4
    city.part = np.concatenate(parts)
    city.owner = np.concatenate(owners)
    city.vertices = np.vstack(vs)
    city.triangles = np.vstack(fs).astype(np.int64)
    return city
