"""A procedural city laid on a reconstructed ground, following its relief.

The city of :mod:`procgen.city` (Parish and Mueller's roads, lots, CSG buildings) is grown
on a square map and fitted over the ground's footprint (up along +z): one city metre
becomes ``scale`` mesh units, so a table-top scan gets a model city and a terrain scan a
town, from the same recipe. Then every piece is put on the ground by casting rays down:

- roads are ribbons resampled along their length and draped: each sample of the centre
  line and of both edges sits ``lift`` above the ground under it, so they climb and dip
  with the relief; a stretch whose samples miss the ground (a hole, the edge of the scan)
  or land on an object is left out;
- a building stands on the lowest ground under its footprint (its foundation cut into
  the slope); it is left out when part of its footprint misses the ground or lies on an
  object, or when the ground under it is steeper than ``max_slope_deg``;
- roofs are the buildings' up-facing faces above the ground floor.

The objects of the reconstruction (what is not ground) keep their place: nothing is laid
where a downward ray meets them first.

>>> import numpy as np
>>> from procgen.terrain import heightfield_to_mesh
>>> from core.meshes import mesh_arrays
>>> v, f = mesh_arrays(heightfield_to_mesh(np.zeros((9, 9)), spacing=0.05))
>>> lay = lay_city(v, f, rng=np.random.default_rng(0))
>>> lay.buildings_kept > 0, round(lay.scale * 600, 3)      # 600 city metres over 0.4 m
(True, 0.4)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.meshes import face_normals, submesh
from core.validate import check_array, check_range, check_rng

__all__ = ["CityLayout", "lay_city"]


@dataclass
class CityLayout:
    """What :func:`lay_city` laid.

    Attributes
    ----------
    roads, walls, roofs : open3d.geometry.TriangleMesh or None
        Draped road ribbons; the buildings without their roofs; the roofs.
    city : procgen.city.City
        The city as grown, in city metres.
    scale : float
        Mesh units per city metre.
    origin : (2,) float64
        Where the city's centre lies on the ground (mesh x, y).
    base : (b,) float64
        Height of each building's base (nan where it was left out).
    buildings_kept, roads_kept : int
        Buildings and road segments laid (of ``len(city.buildings)``, ``len(city.edges)``).
    lift : float
        Height of the roads above the ground, mesh units.
    """

    roads: object
    walls: object
    roofs: object
    city: object
    scale: float
    origin: np.ndarray
    base: np.ndarray
    buildings_kept: int
    roads_kept: int
    lift: float


class _Ground:
    """Downward rays onto the ground (geometry 0) and the objects (geometry 1)."""

    def __init__(self, ground_v, ground_f, object_v, object_f):
        import open3d as o3d

        self.scene = o3d.t.geometry.RaycastingScene()
        for v, f in ((ground_v, ground_f), (object_v, object_f)):
            if v is not None and len(f):
                self.scene.add_triangles(o3d.core.Tensor(np.asarray(v, np.float32)),
                                         o3d.core.Tensor(np.asarray(f, np.uint32)))
        allv = ground_v if object_v is None else np.vstack([ground_v, object_v])
        self.top = float(allv[:, 2].max()) + float(np.ptp(allv, axis=0).max())  # scale-free

    def below(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(z (n,), on_ground (n,) bool)``: the ground's height under each point, and
        whether the first thing a ray down from above meets there is the ground."""
        import open3d as o3d

        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        rays = np.zeros((len(xy), 6), np.float32)
        rays[:, :2], rays[:, 2], rays[:, 5] = xy, self.top, -1.0
        hit = self.scene.cast_rays(o3d.core.Tensor(rays))
        t = hit["t_hit"].numpy().astype(np.float64)
        ok = np.isfinite(t) & (hit["geometry_ids"].numpy() == 0)
        return np.where(ok, self.top - np.where(np.isfinite(t), t, 0.0), np.nan), ok


def _footprint(fp: np.ndarray, angle: float) -> np.ndarray:
    """3 x 3 sample points (corners, edge middles, centre) of a lot, city metres."""
    u = np.array([[i, j] for i in (-1.0, 0.0, 1.0) for j in (-1.0, 0.0, 1.0)]) * fp[2:4]
    c, s = np.cos(angle), np.sin(angle)
    return u @ np.array([[c, s], [-s, c]]) + fp[:2]


def _draped_roads(city, ground: _Ground, to_mesh_xy, step: float, lift: float):
    """Road ribbons resampled every ``step`` city metres and draped on the ground;
    ``(vertices, triangles, segments kept)``."""
    from procgen.city import HIGHWAY_HALF_WIDTH, STREET_HALF_WIDTH

    vs, fs, kept, count = [], [], 0, 0
    for (i, j), hw in zip(city.edges, city.highway, strict=True):
        p, q = city.nodes[i], city.nodes[j]
        length = float(np.linalg.norm(q - p))
        if length <= 0:
            continue
        n = np.array([-(q - p)[1], (q - p)[0]]) / length
        n *= HIGHWAY_HALF_WIDTH if hw else STREET_HALF_WIDTH
        t = np.linspace(0.0, 1.0, max(int(np.ceil(length / step)), 1) + 1)[:, None]
        axis = p + t * (q - p)
        rows = np.stack([axis - n, axis, axis + n], 1)            # (k, 3 across, 2)
        z, ok = ground.below(to_mesh_xy(rows.reshape(-1, 2)))
        z, ok = z.reshape(-1, 3), ok.reshape(-1, 3).all(axis=1)
        quad_ok = ok[:-1] & ok[1:]
        if not quad_ok.any():
            continue
        kept += 1
        xyz = np.concatenate([to_mesh_xy(rows.reshape(-1, 2)),
                              (np.nan_to_num(z) + lift).reshape(-1, 1)], 1)
        k = np.flatnonzero(quad_ok)
        a, b = 3 * k, 3 * (k + 1)     # vertex rows of the two ends of each kept quad
        tris = np.concatenate([np.stack([a + c, b + c, b + c + 1], 1) for c in (0, 1)] +
                              [np.stack([a + c, b + c + 1, a + c + 1], 1) for c in (0, 1)])
        vs.append(xyz)
        fs.append(tris + count)
        count += len(xyz)
    if not vs:
        return np.empty((0, 3)), np.empty((0, 3), np.int64), 0
    return np.vstack(vs), np.vstack(fs).astype(np.int64), kept


def _part(v: np.ndarray, f: np.ndarray):
    """The triangles ``f`` as their own mesh (None when there are none)."""
    return submesh(v, f) if len(f) else None


def lay_city(ground_v: np.ndarray, ground_f: np.ndarray, *, rng: np.random.Generator,
             config=None, object_v: np.ndarray | None = None,
             object_f: np.ndarray | None = None, max_slope_deg: float = 20.0,
             road_step: float = 10.0, lift: float = 0.15) -> CityLayout:
    """Grow a city and lay it on the ground ``(ground_v, ground_f)`` (up along +z).

    Parameters
    ----------
    ground_v, ground_f : arrays
        The ground surface.
    rng : numpy.random.Generator
    config : procgen.city.CityConfig, optional
        The city grown (its ``size`` in city metres spans the ground's longer side;
        default: 600 m, two population centres, a park, no river).
    object_v, object_f : arrays, optional
        The objects standing on the ground: nothing is laid on them.
    max_slope_deg : float
        Buildings stand only where the ground under them rises less than this.
    road_step : float
        Roads are resampled every this many city metres to follow the relief.
    lift : float
        Roads lie this many city metres above the ground.

    Returns
    -------
    CityLayout
    """
    from procgen.city import CityConfig, generate_city

    rng = check_rng(rng)
    gv = check_array(ground_v, "ground_v", shape=(None, 3))
    gf = np.asarray(ground_f, np.int64)
    if len(gf) == 0:
        raise ValueError("ground_f: expected a ground with faces, got 0 triangles")
    slope = check_range(max_slope_deg, "max_slope_deg", 0.0, 90.0, hi_open=True)
    road_step = check_range(road_step, "road_step", 0.0, None, lo_open=True)
    cfg = config or CityConfig(size=600.0, centres=2, parks=1, river_width=0.0)
    city = generate_city(rng, cfg)
    lo, hi = gv[:, :2].min(axis=0), gv[:, :2].max(axis=0)
    scale = float(np.max(hi - lo)) / cfg.size
    origin = 0.5 * (lo + hi)

    def to_mesh_xy(xy):
        return origin + scale * np.asarray(xy, np.float64)

    ground = _Ground(gv, gf, object_v, object_f)
    rv, rf, roads_kept = _draped_roads(city, ground, to_mesh_xy, road_step, lift * scale)
    # each building on the lowest ground under its footprint, or left out
    base = np.full(len(city.buildings), np.nan)
    tan = np.tan(np.radians(slope))
    for i, (fp, fr) in enumerate(zip(city.footprints, city.lot_frames, strict=True)):
        z, ok = ground.below(to_mesh_xy(_footprint(fp, fr[0])))
        if ok.all() and np.ptp(z) <= tan * 2.0 * float(fp[2:4].min()) * scale:
            base[i] = z.min()
    on = (city.part == 0) & np.isfinite(base[np.where(city.part == 0, city.owner, 0)])
    idx = np.flatnonzero(on)
    bv = np.concatenate([to_mesh_xy(city.vertices[idx, :2]),
                         (base[city.owner[idx]] + scale * city.vertices[idx, 2])[:, None]], 1)
    remap = np.full(len(city.vertices), -1, np.int64)
    remap[idx] = np.arange(len(idx))
    bf = remap[city.triangles]
    bf = bf[np.all(bf >= 0, axis=1)]
    walls = roofs = None
    if len(bf):
        up = face_normals(bv, bf)[:, 2] > 0.9
        raised = bv[bf].mean(axis=1)[:, 2] > base[city.owner[idx]][bf[:, 0]] + 1.0 * scale
        roof = up & raised
        walls, roofs = (_part(bv, bf[sel]) for sel in (~roof, roof))
    roads = _part(rv, rf)     # only the samples of kept stretches
    return CityLayout(roads=roads, walls=walls, roofs=roofs, city=city, scale=scale,
                      origin=origin, base=base, buildings_kept=int(np.isfinite(base).sum()),
                      roads_kept=roads_kept, lift=lift * scale)
