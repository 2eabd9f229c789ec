"""Forest worlds to survey: a stand of L-system trees on a fractal terrain, with its truth.

A stand comes from an inventory (a CSV with ``x``, ``y``, ``height`` and optionally ``dbh``,
``crown_radius``, ``crown_dx``/``crown_dy`` (the crown's centre from the stem), ``species``:
:func:`core.io.trees.read_tree_table`) or is procedural
(density, species mix, height distribution, understory; seeded); an inventory's stand can
also grow the trees it does not list (``unlisted``: small trees in its gaps, from their own
seeded generator). Each tree is grown on its
own (:func:`procgen.trees.grow_tree`; or, with ``variants``, one of a few individuals per
species), scaled to its height and crown, given its own needle clusters in metres
(conifers), turned about its stem and stood on the terrain so that its top is exactly at
ground + height.

Coordinates are kept as given: an inventory's projected coordinates (millions of metres)
are split into an ``origin`` (rounded to 10 m) and a local frame; the geometry (and so the
render scene) lives in the local frame, the truth (``trees.csv``, ``dtm.tif``) in the
inventory's coordinates. ``world = local + origin``.

Every triangle carries a part (:data:`acquire.lidar.labels.PARTS`): ground (or road), trunk,
branch, leaf, understory, building. Each tree is two objects (``treeNNNNN.wood``: trunk and
branches, ``treeNNNNN.leaf``) sharing the object id ``NNNNN`` (1-based, the row of
``trees.csv``; the unlisted trees after the listed ones); the ground is object 0, the
understory and buildings the ids after the trees.

A forest scene spec is a scene TOML with a ``[forest]`` table (the fields of
:class:`ForestConfig`, and ``inventory = "FILE.csv"`` relative to the spec)::

    [scene]
    name = "forest"
    seed = 0
    [forest]
    size = 60.0
    density = 500.0
    species = "PIAB:0.7,FASY:0.3"
"""

from __future__ import annotations

import logging
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acquire.lidar.labels import part_code
from acquire.render.materials import Material
from acquire.render.scene import RenderScene, SceneObject
from core.config import Config, from_dict, option, to_dict
from core.files import atomic_dir, write_json, write_toml
from core.io.raster import Raster, write_raster
from core.io.trees import read_tree_table, write_tree_table
from core.meshes import make_mesh
from core.validate import InputError
from data_synth.bundle import SceneBundle
from procgen.allometry import crown_displacement, stand_crowns
from procgen.terrain import fractal_terrain, heightfield_to_mesh, mountain_relief
from procgen.trees import (
    LEAF_AREA_INDEX,
    NEEDLE_CLUSTER,
    NEEDLE_DENSITY,
    SPECIES,
    SUN_CROWN_RATIO,
    TREE_PARTS,
    WHORL_AREA,
    crown_media,
    crown_years,
    grow_tree,
    place_tree,
    species_fallback,
    species_for,
)

__all__ = ["ForestConfig", "ForestBundle", "build_forest", "forest_spec", "parse_species_mix",
           "terrain_height", "write_forest", "forest_from_spec", "MATERIALS", "PART_COLORS",
           "UNDERSTORY_DENSITY", "SHADE_TOLERANT", "SAPLING_HEIGHT", "SHRUB_HEIGHT",
           "regeneration_species"]

log = logging.getLogger(__name__)

RELIEF_STREAM = 2  # the relief's generator: default_rng([seed, RELIEF_STREAM])
STEM_SINK = 0.3  # metres: stems start this far below the ground (no gap on a slope)

UNDERSTORY_DENSITY = 2044.0
"""Stems per hectare of the understory by default: saplings over 1.3 m tall and up to 10 cm
dbh, all species, measured on 313 plots of the mountain beech and silver fir forests of
Gorski kotar (Teslak et al. 2016, *Stand regeneration characteristics of beech and fir
forests in Gorski kotar region*, South-east European Forestry 7(2): 99-108,
doi:10.15177/seefor.16-15)."""

SHADE_TOLERANT = frozenset({"PIAB", "ABAL", "ABCO", "FASY", "ACPS", "GENC"})
"""Species whose saplings grow under a closed canopy (the understory's regeneration);
pines, larch, Douglas-fir, oak and birch need gaps (Ellenberg's light figures)."""

SAPLING_HEIGHT = (1.3, 8.0, 1.5)
"""Saplings' heights (m): from breast height to the height of a 10 cm dbh at h/d 80, the
excess over 1.3 m exponential of this scale (the inverse-J of regeneration height classes;
the scale is ours)."""

SHRUB_HEIGHT = (0.5, 2.5)
"""Shrubs' heights (m), uniform; crown radius 0.4 x height."""

# near-infrared reflectances (905, 1064, 1550 nm), typical values of the spectral
# libraries: green leaves are bright at 905-1064 nm and darker at 1550 nm (water)
MATERIALS = {
    "ground": Material(albedo=(0.30, 0.25, 0.18), lidar_reflectance=(0.30, 0.33, 0.38)),
    "road": Material(albedo=(0.12, 0.12, 0.13), lidar_reflectance=(0.12, 0.13, 0.15)),
    "wood": Material(albedo=(0.35, 0.25, 0.17), lidar_reflectance=(0.35, 0.38, 0.40)),
    "leaf": Material(albedo=(0.10, 0.30, 0.08), lidar_reflectance=(0.50, 0.48, 0.25)),
    "needle": Material(albedo=(0.06, 0.20, 0.06), lidar_reflectance=(0.42, 0.40, 0.20)),
    "understory": Material(albedo=(0.12, 0.32, 0.10), lidar_reflectance=(0.45, 0.44, 0.24)),
    "building": Material(albedo=(0.55, 0.52, 0.48), lidar_reflectance=(0.35, 0.35, 0.35)),
}


@dataclass
class ForestConfig(Config):
    """A forest stand: procedural, or grown from an inventory."""

    size: float = option(80.0, unit="m", range="[10, 2000]",
                         help="side of a procedural stand (an inventory's stand is its trees' "
                              "extent)")
    margin: float = option(10.0, unit="m", range="[0, 500]",
                           help="terrain beyond the stand on every side")
    density: float = option(400.0, unit="1/ha", range="[0, 5000]",
                            help="trees per hectare of a procedural stand")
    species: str = option("PIAB:0.6,FASY:0.4",
                          help="species mix of a procedural stand, CODE:share,... (codes: "
                               + ", ".join(SPECIES) + ")")
    height_mean: float = option(22.0, unit="m", range="(0, 120]", help="mean tree height")
    height_sd: float = option(4.0, unit="m", range="[0, 50]",
                              help="standard deviation of tree heights")
    # the understory: what an inventory's threshold leaves out below the stand
    understory: float | None = option(None, unit="1/ha", range="[0, 20000]",
                                      help="stems per hectare of regeneration and shrubs "
                                           "below the inventory's threshold, added to every "
                                           "stand (0: none; default: "
                                           f"{UNDERSTORY_DENSITY:.0f}, saplings of "
                                           "mountain fir-beech forests, Teslak et al. 2016)")
    regeneration: float | None = option(None, range="[0, 1]",
                                        help="share of the understory's stems that are "
                                             "saplings of the stand's shade-tolerant species "
                                             "(1.3-8 m), the rest shrubs (0.5-2.5 m) "
                                             "(default: those species' share of the stand)")
    unlisted: float = option(0.0, unit="1/ha", range="[0, 5000]",
                             help="an inventory's stand: trees per hectare it does not list "
                                  "(small trees its survey or segmentation missed), grown "
                                  "where no listed crown reaches, of its species")
    unlisted_height: float = option(8.0, unit="m", range="[2, 120]",
                                    help="mean height of the unlisted trees")
    unlisted_height_sd: float = option(4.0, unit="m", range="[0, 50]",
                                       help="standard deviation of the unlisted trees' "
                                            "heights (at least 2 m each)")
    relief: float = option(2.0, unit="m", range="[0, 200]",
                           help="terrain height standard deviation")
    terrain_res: float = option(1.0, unit="m", range="(0, 20]",
                                help="terrain grid spacing at most this")
    elevation: float = option(0.0, unit="m", help="terrain mean elevation")
    # -- a mountainside's relief (procgen.terrain.mountain_relief; its own seeded stream)
    slope: float = option(0.0, unit="deg", range="[0, 45]",
                          help="mean slope of the stand's ground, relief and features "
                               "included (0: no tilt)")
    aspect: float = option(180.0, unit="deg", range="[0, 360)",
                           help="direction the slope faces (downhill), clockwise from north")
    slope_breaks: int = option(0, range="[0, 20]",
                               help="breaks of slope across the fall line (the slope "
                                    "alternates between steeper and gentler)")
    terraces: int = option(0, range="[0, 20]",
                           help="terraces down the slope: benches and risers")
    cliffs: int = option(0, range="[0, 10]", help="cliffs across the slope")
    cliff_height: float = option(4.0, unit="m", range="(0, 50]",
                                 help="height of each cliff (a face over one terrain cell)")
    ravines: int = option(0, range="[0, 10]", help="V-shaped ravines down the fall line")
    ravine_depth: float = option(3.0, unit="m", range="(0, 30]",
                                 help="depth of each ravine (4 times as wide)")
    boulders: float = option(0.0, unit="1/ha", range="[0, 2000]",
                             help="boulders (part of the ground: 0.5-1.5 m in radius)")
    roads: bool = option(False, help="a few roads and buildings of the procedural city")
    variants: int = option(0, range="[0, 32]",
                           help="individuals grown per species, each tree a scaled copy of "
                                "one (0: every tree grown on its own)")
    needle_cluster: float = option(NEEDLE_CLUSTER, unit="m", range="[0.02, 1]",
                                   help="side of a conifer's needle cluster (a triangle)")
    needle_density: float = option(NEEDLE_DENSITY, unit="1/m2", range="(0, 2000]",
                                   help="needle clusters per square metre of a conifer "
                                        "branch's spray")
    whorl_area: float = option(WHORL_AREA, unit="m2", range="(0, 100]",
                               help="crown projection a conifer's whorl fills with sprays "
                                    "of its species' width; a crown with more area per "
                                    "whorl widens its sprays in proportion")
    leaf_area_index: float = option(LEAF_AREA_INDEX, unit="m2/m2", range="[0, 20]",
                                    help="broadleaf crowns: one-sided leaf area per m² of "
                                         "crown projection, their leaves a turbid medium "
                                         "in the crown's envelope (European beech 5.6-9.5, "
                                         "Leuschner et al. 2006); 0: the L-system's leaf "
                                         "clusters as polygons")
    sun_crown: float = option(SUN_CROWN_RATIO, range="[1, 20]",
                              help="broadleaf crowns: leaf area density of the sun crown "
                                   "(the crown's upper third) over the shade crown's below "
                                   "(leaves peak in the outer, lit layer: Hagemeier and "
                                   "Leuschner 2019); 1: uniform through the envelope")
    plastic_crowns: bool = option(True, help="crowns whose offsets the inventory does "
                                  "not give move from their stems towards their growing "
                                  "space (their cell of the stand's power diagram of crown "
                                  "radii: procgen.allometry.crown_displacement), as crowns "
                                  "grow into gaps; off: centred on their stems")
    crs: str = option("", help="coordinate system of the inventory (EPSG:CODE or WKT; "
                               "empty: none)")
    weber_penn: str = option("", help="species grown with Weber & Penn's model "
                                      "(procgen.weber_penn) instead of the L-system trees: "
                                      "'all' (PIAB, ABAL, PISY, LADE, FASY, ACPS: their "
                                      "species files) or CODE=species,... (any shipped "
                                      "species); empty: none")
    weber_penn_lod: str = option("cards", choices=("cards", "full"),
                                 help="leaves of the Weber & Penn trees: one card a twig, or "
                                      "every leaf (millions of triangles a tree)")


@dataclass
class ForestBundle(SceneBundle):
    """A forest scene and its truth (coordinates of the inventory: ``local + origin``).

    Attributes
    ----------
    trees : dict of (n,) arrays
        ``tree_id``, ``x``, ``y``, ``z_ground``, ``height``, ``crown_radius``, ``dbh``,
        ``species``, ``listed`` (1: the inventory's or the procedural stand's; 0: an
        unlisted tree, ``ForestConfig.unlisted``).
    dtm : Raster
        The terrain's heights on its grid (exact: the ground mesh is this grid).
    inventory_path : Path or None
    """

    trees: dict = field(default_factory=dict)
    dtm: Raster | None = None
    inventory_path: Path | None = None


def parse_species_mix(text: str, *, path=None, field_name: str = "forest.species"):
    """``"PIAB:0.6,FASY:0.4"`` -> ``(codes, shares summing to 1)``.

    >>> parse_species_mix("piab:3, FASY:1")
    (['PIAB', 'FASY'], [0.75, 0.25])
    """
    codes, shares = [], []
    for item in str(text).split(","):
        if not item.strip():
            continue
        name, _, share = item.partition(":")
        try:
            w = float(share) if share.strip() else 1.0
        except ValueError:
            raise InputError(f"expected CODE:share, got {item.strip()!r}", path=path,
                             field=field_name) from None
        if not w > 0:
            raise InputError(f"expected a positive share, got {item.strip()!r}", path=path,
                             field=field_name)
        codes.append(species_for(name).code)
        shares.append(w)
    if not codes:
        raise InputError("expected at least one species", path=path, field=field_name)
    total = sum(shares)
    return codes, [w / total for w in shares]


def terrain_height(dtm: Raster, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height of the triangulated terrain at ``x, y (n,)`` (exactly the ground mesh).

    The grid's cells are split along the diagonal from sample ``[i, j]`` to ``[i+1, j+1]``
    as :func:`procgen.terrain.heightfield_to_mesh` does; points outside are clamped.
    """
    z = dtm.values
    r, c = z.shape
    u = np.clip((np.asarray(x, float) - dtm.x0) / dtm.res, 0, c - 1)
    v = np.clip((np.asarray(y, float) - dtm.y0) / dtm.res, 0, r - 1)
    j = np.minimum(np.floor(u).astype(np.int64), c - 2)
    i = np.minimum(np.floor(v).astype(np.int64), r - 2)
    fu, fv = u - j, v - i
    za, zb, zc, zd = z[i, j], z[i, j + 1], z[i + 1, j], z[i + 1, j + 1]
    lower = fu >= fv  # triangle (a, b, d)
    return np.where(lower, za + fu * (zb - za) + fv * (zd - zb),
                    za + fv * (zc - za) + fu * (zd - zc))


def _procedural_trees(cfg: ForestConfig, rng: np.random.Generator, *, path) -> dict:
    codes, shares = parse_species_mix(cfg.species, path=path)
    area = cfg.size ** 2
    n = int(rng.poisson(cfg.density * area / 1e4))
    min_d = 0.5 * np.sqrt(1e4 / max(cfg.density, 1e-9))
    pts = np.empty((0, 2))
    tries = 0
    while len(pts) < n and tries < 30:  # dart throwing: no two stems closer than min_d
        tries += 1
        cand = rng.uniform(0, cfg.size, size=(2 * n, 2))
        for p in cand:
            if len(pts) >= n:
                break
            if len(pts) == 0 or np.min(np.sum((pts - p) ** 2, axis=1)) >= min_d ** 2:
                pts = np.vstack([pts, p])
    m = len(pts)
    h = np.maximum(rng.normal(cfg.height_mean, cfg.height_sd, m), 2.0)
    sp = np.array(codes)[rng.choice(len(codes), size=m, p=shares)] if m else np.empty(0, str)
    return {"x": pts[:, 0], "y": pts[:, 1], "height": h, "species": sp}


def _has_relief(cfg: ForestConfig) -> bool:
    return bool(cfg.slope or cfg.slope_breaks or cfg.terraces or cfg.cliffs or cfg.ravines
                or cfg.boulders)


def _terrain(cfg: ForestConfig, lo: np.ndarray, hi: np.ndarray, rng,
             relief_rng: np.random.Generator | None = None) -> Raster:
    extent = float(max(hi - lo)) + 2 * cfg.margin
    n = 2
    while extent / (2 ** n) > cfg.terrain_res:
        n += 1
    size = 2 ** n + 1
    z = fractal_terrain(size, rng=rng, method="fbm", hurst=0.8, height=cfg.relief,
                        frequency=max(extent / 80.0, 1.0), octaves=6)
    res = extent / (size - 1)
    if relief_rng is not None:
        stand = (cfg.margin, cfg.margin, extent - cfg.margin, extent - cfg.margin)
        z = mountain_relief(z, spacing=res, rng=relief_rng, slope=cfg.slope,
                            aspect=cfg.aspect, slope_breaks=cfg.slope_breaks,
                            terraces=cfg.terraces, cliffs=cfg.cliffs,
                            cliff_height=cfg.cliff_height, ravines=cfg.ravines,
                            ravine_depth=cfg.ravine_depth, boulders=cfg.boulders, region=stand)
    return Raster(z + cfg.elevation, x0=float(lo[0] - cfg.margin),
                  y0=float(lo[1] - cfg.margin), res=res)


def _tree_table(cfg, inventory, rng, path):
    if inventory is not None:
        t = read_tree_table(inventory, required=("x", "y", "height"))
        n = len(t["x"])
        sp = (_species_logged(t["species"], inventory) if "species" in t
              else np.full(n, "GENB"))
        return {"x": t["x"], "y": t["y"], "height": t["height"], "species": sp,
                "dbh": t.get("dbh"), "crown_radius": t.get("crown_radius"),
                "crown_dx": t.get("crown_dx"), "crown_dy": t.get("crown_dy")}
    return _procedural_trees(cfg, rng, path=path)


def _species_logged(names, path) -> np.ndarray:
    """The species codes of an inventory's names; each unknown name is grown as the closest
    functional type (:func:`procgen.trees.species_fallback`) and the log says so, once."""
    names = np.asarray(names, str)
    uniq, inv = np.unique(names, return_inverse=True)
    codes = []
    for name in uniq.tolist():
        sp, why = species_fallback(name)
        if why is not None:
            log.warning("%s: %s", path, why)
        codes.append(sp.code)
    return np.array(codes, str)[inv.ravel()] if len(codes) else np.empty(0, str)


def _allometric_crowns(t, dtm_local, xl, yl, zg, origin, area_ha) -> dict:
    """Crown ratios and radii of the listed trees from the species' allometries
    (:func:`procgen.allometry.stand_crowns`; NaN for species they do not cover), with the
    slope and aspect of the ground at each stem."""
    dbh = t.get("dbh")
    dbh_cm = None if dbh is None else np.asarray(dbh, np.float64) * 100.0
    e = 0.5
    gx = (terrain_height(dtm_local, xl + e, yl) - terrain_height(dtm_local, xl - e, yl)) / (2 * e)
    gy = (terrain_height(dtm_local, xl, yl + e) - terrain_height(dtm_local, xl, yl - e)) / (2 * e)
    # the slope faces down the gradient; aspect clockwise from north (+y)
    aspect = np.degrees(np.arctan2(-gx, -gy)) % 360.0
    return stand_crowns(np.asarray(t["species"], str), height_m=np.asarray(t["height"], float),
                        dbh_cm=dbh_cm, area_ha=area_ha, elevation_m=zg + origin[2],
                        slope=np.hypot(gx, gy), aspect_deg=aspect)


def _crown_offsets(t: dict) -> tuple[np.ndarray, np.ndarray]:
    """Each crown's displacement towards its growing space
    (:func:`procgen.allometry.crown_displacement`), from the crown radii the trees will be
    grown with (the inventory's, else the allometric, else the species' proportion)."""
    h = np.asarray(t["height"], np.float64)
    r = np.full(len(h), np.nan)
    for key in ("crown_radius", "allometric_radius"):
        v = t.get(key)
        if v is not None:
            v = np.asarray(v, np.float64)
            r = np.where(np.isfinite(r) | ~(v > 0), r, v)
    width = np.array([species_for(str(s)).crown_width for s in t["species"]], np.float64)
    r = np.where(np.isfinite(r), r, width * h)
    d = crown_displacement(np.column_stack([t["x"], t["y"]]), np.maximum(r, 0.1))
    return d[:, 0], d[:, 1]


def build_forest(cfg: ForestConfig, *, inventory=None, seed: int = 0, name: str = "forest",
                 spec: dict | None = None, path=None) -> ForestBundle:
    """Grow a stand (from ``inventory``, a CSV path, or procedurally) and its truth.

    Returns
    -------
    ForestBundle
        Its render scene and meshes in the local frame; ``origin`` and the truth
        (``trees``, ``dtm``) in the inventory's coordinates.
    """
    rng = np.random.default_rng(seed)
    t = _tree_table(cfg, inventory, rng, path)
    n = len(t["x"])
    if inventory is not None:
        xy = np.stack([t["x"], t["y"]], 1)
        lo, hi = xy.min(0), xy.max(0)
        origin = np.array([np.floor(lo[0] / 10) * 10, np.floor(lo[1] / 10) * 10, 0.0])
    else:
        lo, hi = np.zeros(2), np.full(2, cfg.size)
        origin = np.zeros(3)
    # the mountainside's features from their own generator: a stand without them is
    # the same as before they existed
    relief_rng = np.random.default_rng([seed, RELIEF_STREAM]) if _has_relief(cfg) else None
    dtm_local = _terrain(cfg, lo - origin[:2], hi - origin[:2], rng, relief_rng)
    xl, yl = t["x"] - origin[0], t["y"] - origin[1]
    zg = terrain_height(dtm_local, xl, yl)
    allo = _allometric_crowns(t, dtm_local, xl, yl, zg, origin,
                              max(float(np.prod(hi - lo)), 100.0) / 1e4)
    t["allometric_ratio"] = allo["crown_ratio"]
    t["allometric_radius"] = allo["crown_radius"]
    t["allometric_dbh"] = np.where(np.isfinite(allo["crown_ratio"]), allo["dbh_cm"] / 100.0,
                                   np.nan)
    if cfg.plastic_crowns and (t.get("crown_dx") is None or t.get("crown_dy") is None):
        t["crown_dx"], t["crown_dy"] = _crown_offsets(t)
    objects, meshes = [], {}
    ground_parts = _ground(cfg, dtm_local, rng, objects, meshes)
    crowns, dbhs = _trees(cfg, t, xl, yl, zg, rng, objects, meshes)
    trees = {"tree_id": np.arange(1, n + 1), "x": t["x"], "y": t["y"],
             "z_ground": zg + origin[2], "height": t["height"], "crown_radius": crowns,
             "dbh": dbhs, "species": np.asarray(t["species"], str),
             "listed": np.ones(n, np.int64)}
    if inventory is not None and cfg.unlisted > 0:
        # their own generator: the listed trees and the understory stay as they were
        urng = np.random.default_rng([seed, 1])
        u = _unlisted_trees(cfg, t, crowns, lo, hi, urng)
        m = len(u["x"])
        if m:
            uxl, uyl = u["x"] - origin[0], u["y"] - origin[1]
            uzg = terrain_height(dtm_local, uxl, uyl)
            ucr, udbh = _trees(cfg, u, uxl, uyl, uzg, urng, objects, meshes, first_id=n + 1)
            new = {"tree_id": np.arange(n + 1, n + m + 1), "x": u["x"], "y": u["y"],
                   "z_ground": uzg + origin[2], "height": u["height"], "crown_radius": ucr,
                   "dbh": udbh, "species": u["species"], "listed": np.zeros(m, np.int64)}
            trees = {k: np.concatenate([trees[k], new[k]]) for k in trees}
        log.info("%d unlisted trees grown in the inventory's gaps (%.0f/ha asked)", m,
                 cfg.unlisted)
    density = UNDERSTORY_DENSITY if cfg.understory is None else cfg.understory
    if density > 0:
        _understory(cfg, density, t["species"], dtm_local, lo - origin[:2], hi - origin[:2],
                    rng, objects, meshes, object_id=len(trees["x"]) + 1)
    del ground_parts
    dtm = Raster(dtm_local.values + origin[2], x0=dtm_local.x0 + origin[0],
                 y0=dtm_local.y0 + origin[1], res=dtm_local.res, crs_wkt=_crs_wkt(cfg.crs))
    spec = spec if spec is not None else forest_spec(cfg, seed=seed, name=name)
    return ForestBundle(spec=spec, render_scene=RenderScene(objects, [], 0.3), meshes=meshes,
                        base_dir=None if path is None else Path(path).parent, origin=origin,
                        crs_wkt=dtm.crs_wkt, trees=trees, dtm=dtm,
                        inventory_path=None if inventory is None else Path(inventory))


def _crs_wkt(crs: str) -> str | None:
    if not crs:
        return None
    from rasterio.crs import CRS

    try:
        return CRS.from_user_input(crs).to_wkt()
    except Exception as e:
        raise InputError(f"not a coordinate system rasterio knows ({e})",
                         field="forest.crs") from None


def _add(objects, meshes, name, V, F, parts, material, object_id, *, leaf_area_density=None):
    # a tree's wood and foliage are two objects cut from one vertex array: each keeps only
    # the vertices its triangles use (else every tree's vertices are held twice over in the
    # mesh, its normals, and the ray caster's world arrays)
    used = np.unique(F)
    if len(used) < len(V):
        remap = np.zeros(len(V), np.int64)
        remap[used] = np.arange(len(used))
        V, F = V[used], remap[F]
    mesh = make_mesh(V, F)
    so = SceneObject(name, mesh, material, np.eye(4), object_id,
                     part_labels=np.asarray(parts, np.uint8),
                     leaf_area_density=leaf_area_density)
    objects.append(so)
    meshes[name] = mesh


def _ground(cfg, dtm: Raster, rng, objects, meshes):
    mesh = heightfield_to_mesh(dtm.values, spacing=dtm.res, origin=(dtm.x0, dtm.y0, 0.0))
    V = np.asarray(mesh.vertices)
    F = np.asarray(mesh.triangles).astype(np.int64)
    parts = np.full(len(F), part_code("ground"), np.uint8)
    if cfg.roads:
        _roads_and_buildings(cfg, dtm, V, F, parts, rng, objects, meshes)
    _add(objects, meshes, "ground", V, F, parts, MATERIALS["ground"], 0)
    return parts


def _unlisted_trees(cfg, t, crowns, lo, hi, rng) -> dict:
    """Trees an inventory does not list, in inventory coordinates: ``cfg.unlisted`` per
    hectare of the stand's extent ``lo``-``hi``, each stem where no listed crown (its
    centre, stem + ``crown_dx/dy``, and radius ``crowns``) reaches and at least its own
    crown radius from the other unlisted stems (a tree the survey missed stands in the
    open: under a listed crown it would be that crown's). Species drawn from the listed
    trees', heights normal (``unlisted_height``, ``unlisted_height_sd``, at least 2 m),
    crown radii from the species' proportion. As many as fit in 100 throws each."""
    m = int(rng.poisson(cfg.unlisted * float(np.prod(hi - lo)) / 1e4))
    cx, cy = np.array(t["x"], float), np.array(t["y"], float)
    if t.get("crown_dx") is not None and t.get("crown_dy") is not None:
        cx = cx + np.nan_to_num(np.asarray(t["crown_dx"], float))
        cy = cy + np.nan_to_num(np.asarray(t["crown_dy"], float))
    listed = np.column_stack([cx, cy])
    sp_all = np.asarray(t["species"], str)
    xs, ys, hs, rs, sps = [], [], [], [], []
    for _ in range(m):
        sp = species_for(str(sp_all[rng.integers(len(sp_all))])) if len(sp_all) else \
            species_for("GENC")
        h = max(float(rng.normal(cfg.unlisted_height, cfg.unlisted_height_sd)), 2.0)
        r = sp.crown_width * h * rng.uniform(0.85, 1.15)
        for _ in range(100):
            p = rng.uniform(lo, hi)
            if np.any(np.sum((listed - p) ** 2, axis=1) < crowns ** 2):
                continue
            if xs and np.any(np.hypot(np.array(xs) - p[0], np.array(ys) - p[1])
                             < np.maximum(np.array(rs), r)):
                continue
            xs.append(p[0])
            ys.append(p[1])
            hs.append(h)
            rs.append(r)
            sps.append(sp.code)
            break
    return {"x": np.array(xs), "y": np.array(ys), "height": np.array(hs),
            "species": np.array(sps, str), "crown_radius": np.array(rs), "dbh": None,
            "crown_dx": None, "crown_dy": None}


def _trees(cfg, t, xl, yl, zg, rng, objects, meshes, *, first_id=1):
    n = len(xl)
    models = {}
    wp, wp_trees = _weber_penn(cfg)
    crowns, dbhs = np.empty(n), np.full(n, np.nan)
    codes = tuple(TREE_PARTS)
    lut = np.array([part_code(p) for p in codes], np.uint8)
    for k in range(n):
        sp = species_for(str(t["species"][k]))
        h = float(t["height"][k])
        allo_ratio = _at(t, "allometric_ratio", k)
        if sp.code in wp:
            model = None
        elif cfg.variants == 0:
            ratio = (allo_ratio if allo_ratio > 0 else sp.crown_ratio) * rng.uniform(0.9, 1.1)
            years = crown_years(h, ratio) if sp.form == "conifer" else 14
            model = grow_tree(sp, rng=rng, years=years, crown_ratio=ratio)
        else:
            if sp.code not in models:
                models[sp.code] = [grow_tree(sp, rng=rng) for _ in range(cfg.variants)]
            model = models[sp.code][int(rng.integers(len(models[sp.code])))]
        cr = _at(t, "crown_radius", k)
        if not cr > 0:
            allo_r = _at(t, "allometric_radius", k)
            cr = (allo_r if allo_r > 0 else sp.crown_width * h) * rng.uniform(0.85, 1.15)
        dbh = _at(t, "dbh", k)
        if not dbh > 0:
            dbh = _at(t, "allometric_dbh", k)
        off = (0.0, 0.0)
        if t.get("crown_dx") is not None and t.get("crown_dy") is not None:
            off = (float(t["crown_dx"][k]), float(t["crown_dy"][k]))
            off = off if np.all(np.isfinite(off)) else (0.0, 0.0)
        if model is None:
            V, F, P, dbh = _species_tree(wp_trees, wp[sp.code], (xl[k], yl[k], zg[k]), h,
                                         float(cr), dbh, rng)
        else:
            V, F, P = place_tree(model, position=(xl[k], yl[k], zg[k] - STEM_SINK),
                                 height=h + STEM_SINK, crown_radius=float(cr),
                                 dbh=float(dbh) if dbh > 0 else None,
                                 azimuth=float(rng.uniform(0, 2 * np.pi)), rng=rng,
                                 needle_cluster=cfg.needle_cluster,
                                 needle_density=cfg.needle_density, crown_offset=off,
                                 whorl_area=cfg.whorl_area)
        crowns[k] = cr
        if dbh > 0:
            dbhs[k] = dbh
        wood = P != codes.index("leaf")
        foliage = MATERIALS["needle" if sp.form == "conifer" else "leaf"]
        medium = sp.form == "broadleaf" and cfg.leaf_area_index > 0 and np.any(~wood)
        parts = (("wood", wood, MATERIALS["wood"]),) if medium else \
            (("wood", wood, MATERIALS["wood"]), ("leaf", ~wood, foliage))
        for suffix, sel, mat in parts:
            if np.any(sel):
                _add(objects, meshes, f"tree{k + first_id:05d}.{suffix}", V, F[sel],
                     lut[P[sel]], mat, k + first_id)
        if medium:  # leaves of centimetres, too many to mesh: the crown as a medium
            layers = crown_media(V[np.unique(F[~wood])], cfg.leaf_area_index,
                                 sun_ratio=cfg.sun_crown)
            for suffix, (ev, ef, lad) in zip(("leaf", "sun"), layers, strict=False):
                _add(objects, meshes, f"tree{k + first_id:05d}.{suffix}", ev, ef,
                     np.full(len(ef), part_code("leaf"), np.uint8), foliage, k + first_id,
                     leaf_area_density=lad)
    return crowns, dbhs


def _weber_penn(cfg):
    """The codes grown with Weber & Penn's model (code -> species) and their grower."""
    if not cfg.weber_penn:
        return {}, None
    from procgen.weber_penn.placement import SpeciesTrees, species_map

    try:
        wp = species_map(cfg.weber_penn, field_name="forest.weber_penn")
    except ValueError as e:
        raise InputError(str(e).partition(": ")[2], field="forest.weber_penn") from None
    return wp, SpeciesTrees(lod=cfg.weber_penn_lod, variants=cfg.variants)


def _species_tree(trees, name, ground, h, cr, dbh, rng):
    """A Weber & Penn tree standing at ``ground`` (its stem sunk as the others), its top at
    ground + ``h``, its crown of radius ``cr``; its dbh the one built."""
    x, y, z = ground
    t = trees.place(name, position=(x, y, z - STEM_SINK), height=h + STEM_SINK,
                    crown_radius=cr, dbh=dbh if dbh > 0 else None,
                    azimuth=float(rng.uniform(0, 2 * np.pi)), rng=rng)
    return t.vertices, t.triangles, t.parts, t.dbh


def _at(t: dict, key: str, k: int) -> float:
    v = t.get(key)
    return float(v[k]) if v is not None else float("nan")


def regeneration_species(species) -> tuple[list[str], list[float]]:
    """The shade-tolerant species of a stand and their shares among its trees
    (:data:`SHADE_TOLERANT`): the understory's saplings. Empty when it has none.

    >>> regeneration_species(["PIAB", "PISY", "FASY", "PIAB"])
    (['FASY', 'PIAB'], [0.25, 0.5])
    """
    sp = np.asarray(species, str)
    codes = sorted({s for s in sp.tolist() if s in SHADE_TOLERANT})
    return codes, [float(np.mean(sp == c)) for c in codes]


def _understory(cfg, density, species, dtm, lo, hi, rng, objects, meshes, *, object_id):
    """``density`` stems per hectare over the stand's extent: saplings of the stand's
    shade-tolerant species (a share ``cfg.regeneration``, by default theirs of the stand;
    heights :data:`SAPLING_HEIGHT`, crowns of their species' proportion) and shrubs
    (:data:`SHRUB_HEIGHT`), at random positions, one object."""
    area = float(np.prod(hi - lo))
    m = int(rng.poisson(density * area / 1e4))
    if m == 0:
        return
    protos = [grow_tree("GENB", rng=rng) for _ in range(2)]
    xy = rng.uniform(lo, hi, size=(m, 2))
    zs = terrain_height(dtm, xy[:, 0], xy[:, 1])
    codes, shares = regeneration_species(species)
    share = sum(shares) if cfg.regeneration is None else cfg.regeneration
    saplings = {}
    if share > 0 and codes:
        # their own generator, seeded by one draw: every share above 0 gives the shrubs the
        # same draws (and a share of 0, no saplings, draws nothing: the stand of before)
        srng = np.random.default_rng(rng.integers(2 ** 63))
        is_sap = srng.random(m) < share
        w = np.array(shares) / np.sum(shares)
        which = srng.choice(len(codes), size=m, p=w)
        lo_h, hi_h, scale = SAPLING_HEIGHT
        cut = 1.0 - np.exp(-(hi_h - lo_h) / scale)  # truncated exponential, inverse CDF
        hs = lo_h - scale * np.log1p(-srng.random(m) * cut)
        models = {c: [grow_tree(c, rng=srng, years=6, crown_ratio=0.85) for _ in range(2)]
                  for c in codes}
        for k in np.flatnonzero(is_sap):
            sp = species_for(codes[which[k]])
            saplings[int(k)] = (models[sp.code][k % 2], float(hs[k]),
                                sp.crown_width * float(hs[k]))
    vs, fs, count = [], [], 0
    for k in range(m):
        h = rng.uniform(*SHRUB_HEIGHT)
        az = float(rng.uniform(0, 2 * np.pi))
        if k in saplings:
            model, hk, rk = saplings[k]
            V, F, _ = place_tree(model, position=(xy[k, 0], xy[k, 1], zs[k] - 0.1), height=hk,
                                 crown_radius=rk, azimuth=az, rng=srng,
                                 needle_cluster=cfg.needle_cluster,
                                 needle_density=cfg.needle_density)
        else:
            V, F, _ = place_tree(protos[k % 2], position=(xy[k, 0], xy[k, 1], zs[k] - 0.1),
                                 height=h, crown_radius=0.4 * h, azimuth=az)
        vs.append(V)
        fs.append(F + count)
        count += len(V)
    F = np.vstack(fs)
    _add(objects, meshes, "understory", np.vstack(vs), F,
         np.full(len(F), part_code("understory"), np.uint8), MATERIALS["understory"], object_id)


def _roads_and_buildings(cfg, dtm, V, F, parts, rng, objects, meshes):
    """Label the ground under the city's roads, and stand its buildings on the terrain."""
    from procgen.city import HIGHWAY_HALF_WIDTH, STREET_HALF_WIDTH, CityConfig, generate_city

    r, c = dtm.values.shape
    extent = dtm.res * (max(r, c) - 1)
    city = generate_city(rng, CityConfig(size=max(extent, 100.0), highway_length=extent / 3,
                                         street_length=extent / 4, snap_radius=extent / 10,
                                         river_width=0.0, parks=0, max_segments=12,
                                         lot_width=14.0, lot_depth=14.0))
    shift = np.array([dtm.x0 + extent / 2, dtm.y0 + extent / 2])
    if len(city.edges) == 0:
        return
    cen = V[F].mean(1)[:, :2] - shift
    a, b = city.nodes[city.edges[:, 0]], city.nodes[city.edges[:, 1]]
    half = np.where(city.highway, HIGHWAY_HALF_WIDTH, STREET_HALF_WIDTH)
    for p, q, hw in zip(a, b, half, strict=True):
        d = q - p
        s = np.clip(((cen - p) @ d) / max(d @ d, 1e-12), 0, 1)
        on = np.hypot(*(cen - p - s[:, None] * d).T) <= hw
        parts[on] = part_code("road")
    bv = city.vertices[city.part == 0]
    if len(bv) == 0:
        return
    keep = np.all(city.part[city.triangles] == 0, axis=1)
    bf = city.triangles[keep]
    owner = city.owner
    bv_all = city.vertices.copy()
    bv_all[:, :2] += shift
    base = np.array([float(np.min(terrain_height(dtm, *bv_all[owner == i, :2].T)))
                     if np.any(owner == i) else 0.0 for i in range(len(city.buildings))])
    on_b = city.part == 0
    bv_all[on_b, 2] += base[owner[on_b]] - 0.5
    used, inv = np.unique(bf, return_inverse=True)
    _add(objects, meshes, "buildings", bv_all[used], inv.reshape(-1, 3),
         np.full(len(bf), part_code("building"), np.uint8), MATERIALS["building"], 10 ** 6)


def forest_spec(cfg: ForestConfig, *, seed: int, name: str = "forest",
                inventory: str | None = None) -> dict:
    """The scene spec (``scene.toml``) that rebuilds this forest."""
    forest = to_dict(cfg)
    if inventory is not None:
        forest["inventory"] = str(inventory)
    return {"scene": {"name": name, "seed": int(seed)}, "forest": forest}


def forest_from_spec(spec: dict, *, path=None, base_dir=None) -> ForestBundle:
    """Build the forest of a spec with a ``[forest]`` table (see the module docstring)."""
    table = dict(spec.get("forest") or {})
    inv = table.pop("inventory", None)
    cfg = from_dict(ForestConfig, table, path=path, prefix="forest.")
    inventory = None
    if inv is not None:
        p = Path(inv)
        inventory = p if p.is_absolute() or base_dir is None else Path(base_dir) / p
    head = spec.get("scene", {})
    return build_forest(cfg, inventory=inventory, seed=int(head.get("seed", 0)),
                        name=str(head.get("name", "forest")), spec=spec, path=path)


PART_COLORS = {"ground": (0.55, 0.45, 0.30), "trunk": (0.35, 0.20, 0.10),
               "branch": (0.65, 0.45, 0.25), "leaf": (0.20, 0.60, 0.15),
               "understory": (0.65, 0.80, 0.20), "building": (0.75, 0.30, 0.30),
               "road": (0.25, 0.25, 0.28), "water": (0.2, 0.4, 0.8), "glass": (0.6, 0.8, 0.9),
               "unlabelled": (0.5, 0.5, 0.5)}
"""Colour of each part in ``mesh.ply`` and the renders."""


def write_forest(bundle: ForestBundle, out_dir) -> Path:
    """Write a forest scene folder atomically: ``scene.toml`` (+ ``inventory.csv``),
    ``mesh.ply`` (local frame; each vertex coloured and labelled by its part, the names in
    ``labels.json``), ``trees.csv`` and ``dtm.tif`` (the truth, in the inventory's
    coordinates), ``materials.json``."""
    from acquire.lidar.labels import PARTS
    from core.io.mesh import write_labeled_mesh

    out = Path(out_dir)
    spec = {k: (dict(v) if isinstance(v, dict) else v) for k, v in bundle.spec.items()}
    spec["scene"]["origin"] = [float(v) for v in bundle.origin]
    objs = bundle.render_scene.objects
    vs, fs, labs, count = [], [], [], 0
    for o in objs:
        v, f = np.asarray(o.mesh.vertices), np.asarray(o.mesh.triangles)
        lab = np.zeros(len(v), np.int64)
        lab[f] = o.part_labels[:, None]
        vs.append(v)
        fs.append(f + count)
        labs.append(lab)
        count += len(v)
    lab = np.concatenate(labs)
    palette = np.array([PART_COLORS[p] for p in PARTS])
    with atomic_dir(out) as tmp:
        if bundle.inventory_path is not None:
            shutil.copyfile(bundle.inventory_path, tmp / "inventory.csv")
            spec["forest"]["inventory"] = "inventory.csv"
        write_toml(tmp / "scene.toml", spec)
        write_labeled_mesh(tmp / "mesh.ply", np.vstack(vs), np.vstack(fs), colors=palette[lab],
                           labels=lab, names=dict(enumerate(PARTS)))
        tr = bundle.trees
        write_tree_table(tmp / "trees.csv", {k: tr[k] for k in (
            "tree_id", "x", "y", "z_ground", "height", "crown_radius", "dbh", "species",
            "listed")})
        write_raster(tmp / "dtm.tif", bundle.dtm)
        write_json(tmp / "materials.json", {
            "origin": bundle.origin.tolist(),
            "objects": len(objs), "trees": int(len(tr["x"])),
            "lidar_reflectance": {name: m.lidar_reflectance for name, m in MATERIALS.items()}})
    return out
