"""Trees in dense mixed stands, flat and on a slope, against the simulator's exact truth.

Procedural stands of 50 x 50 m (``data_synth.forest``: spruce, fir and beech at 300 and
600 trees/ha, with the understory's default regeneration and shrubs, and with none) are
flown by ``scanamp capture lidar`` (riegl-lms-q560, 10 pts/m2) and reconstructed by
``reconstruct lidar`` on the file's own (true) ground class, so the trees are scored apart
from the ground filter: detection F (lidaRtRee's matching, 2.1 m + 0.14 h), height RMSE,
and the error of ``stem_z`` against the true terrain under the matched stems. The sloped
stands tilt the terrain by a plane (a stand-in for the ground engineer's
``--forest.slope``: the fractal relief plus ``tan(slope) x``).

Then the survey of a dense mountain stand as a scanner sees it: PIAB/ABAL/FASY at 600/ha
with the understory's default, flown at 13.5 pts/m2: ground share, share of pulses with
several returns, canopy cover, vegetation heights P50/P95 (the figures of a real survey a
simulated one is held against), and F on it.

``python benchmarks/bench_lidar_trees.py [--quick]``: ``--quick`` flies only the 600/ha
stands.
"""

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SIZE = 50.0
MIX = "PIAB:0.4,ABAL:0.3,FASY:0.3"


class tilted:
    """Within the block, procedural terrains carry a plane rising ``slope_deg`` along +x."""

    def __init__(self, slope_deg: float):
        self.k = float(np.tan(np.radians(slope_deg)))

    def __enter__(self):
        import data_synth.forest as forest

        self._orig = orig = forest._terrain
        k = self.k

        def terrain(cfg, lo, hi, rng, *rest):
            r = orig(cfg, lo, hi, rng, *rest)
            xs, _ = r.centres()
            r.values = r.values + k * (xs[None, :] - xs[0])
            return r

        forest._terrain = terrain
        return self

    def __exit__(self, *exc):
        import data_synth.forest as forest

        forest._terrain = self._orig


def survey(forest_kw: dict, *, slope: float = 0.0, density: float = 10.0,
           seed: int = 3) -> tuple[dict, dict, object, float]:
    """Grow and fly one stand: its points, its true trees, its true terrain and the time
    taken (cached in ``$SCANAMP_BENCH_CACHE`` when set)."""
    import json
    import os

    from acquire.lidar.capture import LidarCaptureConfig
    from core.io.las import read_las
    from core.io.raster import Raster
    from data_synth.forest import ForestConfig, build_forest, write_forest
    from scanamp.methods.lidar import run_lidar_capture

    key = json.dumps([forest_kw, slope, density, seed], sort_keys=True)
    cache = os.environ.get("SCANAMP_BENCH_CACHE")
    f = None
    if cache:
        import hashlib

        f = Path(cache) / f"trees_{hashlib.sha1(key.encode()).hexdigest()[:12]}.npz"
        if f.exists():
            d = np.load(f)
            pts = {k[2:]: d[k] for k in d.files if k.startswith("p_")}
            trees = {k[2:]: d[k] for k in d.files if k.startswith("t_")}
            dtm = Raster(d["dtm"], x0=float(d["dtm_x0"]), y0=float(d["dtm_y0"]),
                         res=float(d["dtm_res"]))
            return pts, trees, dtm, float(d["seconds"])
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d, tilted(slope):
        d = Path(d)
        cfg = ForestConfig(**{"size": SIZE, "margin": 5.0, "relief": 0.5, **forest_kw})
        b = build_forest(cfg, seed=seed)
        write_forest(b, d / "scene")
        run_lidar_capture(str(d / "scene"), LidarCaptureConfig(density=density),
                          d / "survey", bundle=b)
        pts, _ = read_las(d / "survey" / "points.laz")
    seconds = time.perf_counter() - t0
    trees = {k: np.asarray(b.trees[k]) for k in ("x", "y", "height", "z_ground", "species")}
    if f is not None:
        f.parent.mkdir(parents=True, exist_ok=True)
        np.savez(f, **{f"p_{k}": v for k, v in pts.items()},
                 **{f"t_{k}": v for k, v in trees.items()}, dtm=b.dtm.values,
                 dtm_x0=b.dtm.x0, dtm_y0=b.dtm.y0, dtm_res=b.dtm.res, seconds=seconds)
    return pts, trees, b.dtm, seconds


def fly(forest_kw: dict, *, slope: float = 0.0, density: float = 10.0, seed: int = 3,
        config=None) -> dict:
    """Grow, fly and reconstruct one stand; its figures."""
    from data_synth.forest import terrain_height
    from reconstruct.lidar import LidarReconConfig, height_above, reconstruct_points, tree_scores

    pts, listed, dtm, t_fly = survey(forest_kw, slope=slope, density=density, seed=seed)
    inside = ((pts["x"] >= 0) & (pts["x"] <= SIZE) & (pts["y"] >= 0) & (pts["y"] <= SIZE))
    pts = {k: v[inside] for k, v in pts.items()}
    res = reconstruct_points(pts, config=config or LidarReconConfig())
    tr = res.trees
    ref = np.column_stack([listed["x"], listed["y"], listed["height"]])
    det = np.column_stack([tr["x"], tr["y"], tr["height"]])
    s = tree_scores(ref, det)
    from reconstruct.lidar import match_trees

    pairs = match_trees(ref, det)
    true_stem = terrain_height(dtm, tr["x"][pairs[:, 1]], tr["y"][pairs[:, 1]])
    dz = tr["stem_z"][pairs[:, 1]] - true_stem
    xyz = np.column_stack([pts["x"], pts["y"], pts["z"]])
    first = pts["return_number"] == 1
    h = height_above(res.dtm, xyz)
    veg = h[(pts["classification"] != 2) & (h > 2.0)]
    ij = np.floor(xyz[:, :2]).astype(np.int64)
    top = first & (h > 2.0)
    cover = len(np.unique(ij[top, 0] * 1000 + ij[top, 1])) / (SIZE * SIZE)
    from reconstruct.lidar import surface_model

    # a top is seen from above when no other crown stands over it (within 0.5 m of the DSM)
    dsm = surface_model(xyz, res.dtm)
    tops = listed["z_ground"] + listed["height"]
    seen = tops >= dsm.sample(listed["x"], listed["y"]) - 0.5
    s_seen = tree_scores(ref[seen], det)
    return {"trees": len(ref), "found": len(det), "F": s["f"], "height RMSE": s["height_rmse"],
            "seen": int(seen.sum()), "F seen": s_seen["f"],
            "stem_z RMSE": float(np.sqrt(np.mean(dz ** 2))) if len(dz) else np.nan,
            "ground share": float(np.mean(pts["classification"] == 2)),
            "several returns": float(np.mean(pts["number_of_returns"][first] > 1)),
            "canopy cover": float(cover),
            "P50": float(np.percentile(veg, 50)), "P95": float(np.percentile(veg, 95)),
            "first/m2": float(first.sum() / SIZE ** 2), "seconds": t_fly}


def understory_for_cover(cover: float, species: str) -> float:
    """Understory stems per hectare whose crowns, at random, cover ``cover`` of the ground:
    ``-ln(1 - cover) / E[crown area]``, the crowns those of ``data_synth.forest`` (saplings
    of the stand's shade-tolerant species, shrubs of the rest's share)."""
    from data_synth.forest import (
        SAPLING_HEIGHT,
        SHRUB_HEIGHT,
        parse_species_mix,
        regeneration_species,
    )
    from procgen.trees import species_for

    codes, shares = parse_species_mix(species)
    rng = np.random.default_rng(0)
    sp = rng.choice(codes, size=20000, p=shares)
    tol, tshare = regeneration_species(sp)
    lo, hi, scale = SAPLING_HEIGHT
    h = lo - scale * np.log1p(-rng.random(20000) * (1 - np.exp(-(hi - lo) / scale)))
    w = np.array([species_for(c).crown_width for c in rng.choice(tol, 20000, p=np.array(
        tshare) / sum(tshare))]) if tol else np.zeros(20000)
    sap = float(np.mean(np.pi * (w * h) ** 2))
    a, b = SHRUB_HEIGHT
    shrub = np.pi * 0.16 * (b ** 3 - a ** 3) / (3 * (b - a))
    share = sum(tshare)
    return float(-np.log1p(-cover) * 1e4 / (share * sap + (1 - share) * shrub))


def _row(name, r):
    print(f"   {name:34s} trees {r['trees']:3d} (tops seen {r['seen']:3d}) found "
          f"{r['found']:3d}  F {r['F']:.3f} (against the tops seen {r['F seen']:.3f})  "
          f"height RMSE {r['height RMSE']:.2f} m  stem_z RMSE {r['stem_z RMSE']:.2f} m  "
          f"({r['seconds']:.0f} s)")


def main():
    from data_synth.forest import UNDERSTORY_DENSITY

    quick = "--quick" in sys.argv
    print("trees against the truth (10 pts/m2, riegl-lms-q560, the file's ground class):")
    print(f"   (understory default {UNDERSTORY_DENSITY:.0f}/ha; the third of each: crowns "
          "covering 50 % of the ground at random)")
    for density in ((600.0,) if quick else (300.0, 600.0)):
        for slope in (0.0, 35.0):
            for under in (None, 0.0, understory_for_cover(0.5, MIX)):
                kw = {"density": density, "species": MIX, "understory": under}
                r = fly(kw, slope=slope)
                _row(f"{density:.0f}/ha, {slope:.0f} deg, understory "
                     f"{'default' if under is None else f'{under:.0f}/ha'}", r)
    print("a dense PIAB/ABAL/FASY stand at 13.5 pts/m2 (riegl-lms-q560), as a survey sees it:")
    r = fly({"density": 600.0, "species": "PIAB:0.35,ABAL:0.35,FASY:0.3"}, density=13.5,
            slope=20.0)
    print(f"   ground share {r['ground share']:.3f} (a dense mountain survey: ~0.09), pulses "
          f"with several returns {r['several returns']:.3f} (~0.33), canopy cover "
          f"{r['canopy cover']:.1%}, vegetation height P50 {r['P50']:.1f} m, P95 "
          f"{r['P95']:.1f} m, first returns {r['first/m2']:.1f}/m2; F {r['F']:.3f}")


if __name__ == "__main__":
    main()
