"""The ground filter on simulated stands of growing relief (issue 31: the cloth on hills).

Procedural stands of 60 x 60 m (data_synth.forest, ``relief`` = the terrain's height
standard deviation: 0, 2, 5 and 10 m) flown by ``scanamp capture lidar`` (riegl-lms-q560,
4 pts/m2); the filter classifies them with the simulation's classes removed. Against the
simulation's truth: type I (true ground called non-ground), type II (the rest called
ground) and the RMSE of the DTM (the ground's TIN, 1 m cells) against the true terrain over
the stand. Surveys are cached in ``$SCANAMP_BENCH_CACHE`` (a temporary folder otherwise).
Each stand is classified three ways: the fixed 6-degree densification of before, the
densification with its slope term and corner planes but no lower-surface trim, and the
defaults.
"""

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

RELIEFS = (0.0, 2.0, 5.0, 10.0)
SIZE = 60.0


def survey(relief: float, cache: Path):
    """Points (x, y, z, last, truth ground) and the true terrain of a stand."""
    f = cache / f"stand_relief{relief:g}.npz"
    if f.exists():
        d = np.load(f)
        return d["xyz"], d["last"], d["truth"], d["dtm_xyz"]
    from acquire.lidar.capture import LidarCaptureConfig
    from core.io.las import AsprsClass, read_las
    from data_synth.forest import ForestConfig, build_forest, terrain_height, write_forest
    from scanamp.methods.lidar import run_lidar_capture

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        cfg = ForestConfig(size=SIZE, margin=5.0, relief=relief, density=400.0, variants=2)
        b = build_forest(cfg, seed=3)
        write_forest(b, d / "scene")
        run_lidar_capture(str(d / "scene"), LidarCaptureConfig(density=4.0), d / "survey",
                          bundle=b)
        pts, _ = read_las(d / "survey" / "points.laz")
    xyz = np.column_stack([pts["x"], pts["y"], pts["z"]])
    last = pts["return_number"] >= pts["number_of_returns"]
    truth = pts["classification"] == AsprsClass.GROUND
    lo = xyz[truth, :2].min(axis=0) + cfg.margin  # the stand, without its margin
    xs = np.arange(lo[0] + 0.5, lo[0] + SIZE, 1.0)
    ys = np.arange(lo[1] + 0.5, lo[1] + SIZE, 1.0)
    X, Y = np.meshgrid(xs, ys)
    dtm_xyz = np.column_stack([X.ravel(), Y.ravel(), terrain_height(b.dtm, X.ravel(), Y.ravel())])
    np.savez(f, xyz=xyz, last=last, truth=truth, dtm_xyz=dtm_xyz)
    return xyz, last, truth, dtm_xyz


def score(xyz, last, truth, dtm_xyz, options=None):
    from reconstruct.lidar.ground import classify_ground
    from reconstruct.lidar.rasters import dtm_from_ground, height_above

    t = time.process_time()
    g = classify_ground(xyz, last=last, options=options)
    cpu = time.process_time() - t
    t1 = 100 * np.mean(~g[truth])
    t2 = 100 * np.mean(g[~truth])
    lo, hi = dtm_xyz[:, :2].min(axis=0) - 0.5, dtm_xyz[:, :2].max(axis=0) + 0.5
    dtm = dtm_from_ground(xyz[g], bounds=(*lo, *hi), res=1.0)
    rmse = float(np.sqrt(np.mean(height_above(dtm, dtm_xyz) ** 2)))
    return t1, t2, rmse, cpu


def main():
    from reconstruct.lidar.ground import GroundOptions

    cache = Path(os.environ.get("SCANAMP_BENCH_CACHE") or tempfile.mkdtemp())
    cache.mkdir(parents=True, exist_ok=True)
    variants = {"fixed angle (before)": GroundOptions(densify_local=False,
                                                      densify_slope_gain=0.0, lower_offset=0.0),
                "no lower surface": GroundOptions(lower_offset=0.0),
                "defaults": GroundOptions()}
    print(f"   {'options':24s} {'relief (m sd)':>13s} {'points':>7s} {'type I %':>9s} "
          f"{'type II %':>9s} {'DTM RMSE m':>10s} {'CPU s':>6s}")
    for r in RELIEFS:
        xyz, last, truth, dtm_xyz = survey(r, cache)
        for name, o in variants.items():
            t1, t2, rmse, cpu = score(xyz, last, truth, dtm_xyz, options=o)
            print(f"   {name:24s} {r:13g} {len(xyz):7d} {t1:9.1f} {t2:9.2f} {rmse:10.3f} "
                  f"{cpu:6.1f}")


if __name__ == "__main__":
    main()
