"""``scanamp reconstruct lidar POINTS.laz --out DIR``: terrain, canopy and trees of a survey.

For simulated and real surveys alike: read the LAS/LAZ file; classify the ground with the
cloth simulation filter when the file has no ground class (ASPRS 2) or with
``reclassify``; interpolate the DTM from the ground, the CHM from every point's height
above it; find the trees (tops and crowns). Writes, in the file's coordinates and CRS:

- ``dtm.tif``, ``chm.tif`` -- GeoTIFF rasters (:mod:`core.io.raster`);
- ``trees.csv`` -- ``tree_id, x, y, height, crown_area, stem_z`` (the top, its height above
  the ground at the stem, the crown's area, the ground's elevation at the stem);
- ``crowns.gpkg`` -- the crowns as polygons (layer ``crowns``: ``tree_id``, ``height``,
  ``crown_area``, ``stem_z``), a GeoPackage GIS tools open;
- ``classified.laz`` -- the points with their ground class (2) and, when the filter ran,
  the water it found (9); others keep theirs (a point the file called ground that the
  filter did not is 1, unclassified);
- ``report.json`` -- counts, shares, timings.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.config import Config, option
from core.files import atomic_dir, json_data, write_json
from core.io.las import AsprsClass, LasWriter, read_las
from core.io.raster import write_raster
from core.io.trees import write_tree_table
from core.io.vector import write_polygons
from core.validate import InputError
from reconstruct.lidar.crowns import crown_polygons
from reconstruct.lidar.ground import GroundOptions, classify_ground
from reconstruct.lidar.rasters import canopy_height, dtm_from_ground, surface_model
from reconstruct.lidar.trees import TreeOptions, detect_trees
from reconstruct.result import ReconstructionResult

__all__ = ["LidarReconConfig", "LidarResult", "reconstruct_points", "run",
           "first_return_spacing"]

log = logging.getLogger(__name__)

#: low and high noise: never ground, never canopy
NOISE_CLASSES = (AsprsClass.LOW_NOISE, AsprsClass.HIGH_NOISE)


@dataclass
class LidarReconConfig(Config):
    """Options of ``scanamp reconstruct lidar``."""

    reclassify: bool = option(False, help="classify the ground even when the file has a "
                                          "ground class")
    resolution: float = option(0.5, unit="m", range="(0, 50]", help="DTM and CHM cell size")
    ground: GroundOptions = option(default_factory=GroundOptions,
                                   help="the cloth simulation filter")
    trees: TreeOptions = option(default_factory=TreeOptions, help="the tree detection")


@dataclass
class LidarResult:
    """What :func:`reconstruct_points` found (rasters and trees in the points' coordinates)."""

    ground: np.ndarray  # (n,) bool
    reclassified: bool
    water: np.ndarray  # (n,) bool: found by the filter (none when the file's class is used)
    dtm: object  # Raster
    chm: object  # Raster
    trees: dict  # x, y, height, crown_area, stem_z (k,), crowns (rows, cols)
    timings: dict


def reconstruct_points(points: dict, *, config: LidarReconConfig | None = None,
                       crs_wkt: str | None = None, path=None) -> LidarResult:
    """Ground, DTM, CHM and trees of a point cloud given as LAS dimensions.

    Parameters
    ----------
    points : dict of (n,) arrays
        ``x, y, z`` (float64), and when present ``classification``, ``return_number``,
        ``number_of_returns``.
    config : LidarReconConfig, optional
    crs_wkt : str, optional
        Carried to the rasters.
    path : optional
        The file named in errors.
    """
    c = config or LidarReconConfig()
    xyz = np.column_stack([points["x"], points["y"], points["z"]])
    n = len(xyz)
    if n == 0:
        raise InputError("the file has no points", path=path, field="points")
    cls = points.get("classification")
    noise = np.isin(cls, NOISE_CLASSES) if cls is not None else np.zeros(n, bool)
    t = {}
    t0 = time.perf_counter()
    has_ground = cls is not None and np.any(cls == AsprsClass.GROUND)
    reclassified = bool(c.reclassify or not has_ground)
    if reclassified:
        last = None
        if "return_number" in points and "number_of_returns" in points:
            last = points["return_number"] >= points["number_of_returns"]
        keep = np.flatnonzero(~noise)
        ground = np.zeros(n, bool)
        water = np.zeros(n, bool)
        if len(keep):
            w = np.zeros(len(keep), bool)
            ground[keep] = classify_ground(xyz[keep], options=c.ground,
                                           last=None if last is None else last[keep], water=w)
            water[keep] = w
    else:
        ground = cls == AsprsClass.GROUND
        water = np.zeros(n, bool)
    t["ground_s"] = time.perf_counter() - t0
    if ground.sum() < 3:
        raise InputError(f"no ground: {int(ground.sum())} ground points, a terrain needs at "
                         "least 3", path=path, field="classification")
    t0 = time.perf_counter()
    lo, hi = xyz[:, :2].min(axis=0), xyz[:, :2].max(axis=0)
    try:
        dtm = dtm_from_ground(xyz[ground], bounds=(*lo, *hi), res=c.resolution,
                              crs_wkt=crs_wkt)
    except ValueError as e:
        raise InputError(str(e), path=path, field="classification") from None
    chm = canopy_height(xyz[~noise], dtm)
    dsm = surface_model(xyz[~noise], dtm)
    t["rasters_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    trees = detect_trees(chm, options=c.trees, dsm=dsm, dtm=dtm,
                         spacing=first_return_spacing(points, lo, hi, ~noise))
    t["trees_s"] = time.perf_counter() - t0
    return LidarResult(ground, reclassified, water, dtm, chm, trees, t)


def first_return_spacing(points: dict, lo, hi, keep: np.ndarray) -> float | None:
    """Mean spacing of a survey's first returns (``1 / sqrt(density)``, m) over its extent
    ``lo``-``hi``: every kept point when the file has no return numbers; None for an
    extent of no area."""
    area = float(np.prod(np.asarray(hi, float) - np.asarray(lo, float)))
    first = keep if "return_number" not in points else keep & (points["return_number"] <= 1)
    n = int(first.sum())
    return float(np.sqrt(area / n)) if area > 0 and n > 0 else None


def _classified(points: dict, ground: np.ndarray, water: np.ndarray | None = None) -> np.ndarray:
    cls = points.get("classification")
    out = (np.ones(len(ground), np.uint8) if cls is None else np.asarray(cls, np.uint8).copy())
    out[(out == AsprsClass.GROUND) & ~ground] = AsprsClass.UNCLASSIFIED
    if water is not None:
        out[water] = AsprsClass.WATER
    out[ground] = AsprsClass.GROUND
    return out


def run(config: LidarReconConfig, points_path, out_dir) -> ReconstructionResult:
    """Reconstruct terrain, canopy and trees of a LAS/LAZ file into ``out_dir``; the folder
    and its report."""
    points_path = Path(points_path)
    t0 = time.perf_counter()
    points, info = read_las(points_path)
    t_read = time.perf_counter() - t0
    res = reconstruct_points(points, config=config, crs_wkt=info.crs_wkt, path=points_path)
    tr = res.trees
    n = info.point_count
    cls = _classified(points, res.ground, res.water)
    veg_h = _heights(points, res)
    report = {
        "input": str(points_path), "points": n, "crs": info.crs_wkt,
        "ground": {"reclassified": res.reclassified, "points": int(res.ground.sum()),
                   "share": float(res.ground.mean()), "water_points": int(res.water.sum())},
        "rasters": {"resolution_m": config.resolution, "shape": list(res.dtm.values.shape)},
        "trees": {"count": int(len(tr["x"])),
                  "height_p50_m": float(np.median(tr["height"])) if len(tr["x"]) else None},
        "vegetation_height": veg_h,
        "timings": {"read_s": t_read, **res.timings},
    }
    t0 = time.perf_counter()
    with atomic_dir(out_dir) as tmp:
        write_raster(tmp / "dtm.tif", res.dtm)
        write_raster(tmp / "chm.tif", res.chm)
        ids = np.arange(1, len(tr["x"]) + 1)
        write_tree_table(tmp / "trees.csv", {"tree_id": ids, "x": tr["x"], "y": tr["y"],
                                             "height": tr["height"],
                                             "crown_area": tr["crown_area"],
                                             "stem_z": tr["stem_z"]})
        write_polygons(tmp / "crowns.gpkg", crown_polygons(tr["crowns"], res.chm),
                       {"tree_id": ids, "height": tr["height"], "crown_area": tr["crown_area"],
                        "stem_z": tr["stem_z"]}, layer="crowns", crs_wkt=info.crs_wkt)
        _write_classified(tmp / "classified.laz", points, info, cls)
        report["timings"]["write_s"] = time.perf_counter() - t0
        write_json(tmp / "report.json", report)
    return ReconstructionResult(Path(out_dir), json_data(report))


def _heights(points: dict, res: LidarResult) -> dict:
    from reconstruct.lidar.rasters import height_above

    xyz = np.column_stack([points["x"], points["y"], points["z"]])
    h = height_above(res.dtm, xyz)
    veg = h[(~res.ground) & (h > 2.0)]
    return {"p50_m": float(np.percentile(veg, 50)) if len(veg) else None,
            "p95_m": float(np.percentile(veg, 95)) if len(veg) else None,
            "above_2m_share": float(len(veg) / len(h))}


def _write_classified(path: Path, points: dict, info, cls: np.ndarray) -> None:
    extra = {k: np.asarray(points[k]).dtype for k in info.extra_dims}
    out = {k: v for k, v in points.items()}
    out["classification"] = cls
    for name in ("return_number", "number_of_returns"):  # some surveys write 0 for unknown
        if name in out:
            out[name] = np.clip(out[name], 1, 15)
    origin = np.floor(np.array([points["x"].min(), points["y"].min(), points["z"].min()]))
    scale = float(min(info.scales.min(), 0.001)) if len(info.scales) else 0.001
    with LasWriter(path, origin=origin, scale=scale, extra=extra, crs_wkt=info.crs_wkt) as w:
        step = 1_000_000
        for a in range(0, len(cls), step):
            w.write({k: v[a:a + step] for k, v in out.items()})
