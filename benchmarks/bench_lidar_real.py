"""Real airborne LiDAR (../shared/data/real/lidar, two tiles of the R package lidR, GPL-3).

1. ``Topography.laz`` (285 x 285 m of forested hillside, 73,403 points, its own ground class
   2 and water class 9) with its classes removed: our ground (the cloth simulation filter)
   against its own -- total error, type I and II, reported: its class 2 is a sparse lower
   envelope under a layer of grass and shrubs its pulses cannot split from the ground
   (docs/lidar.md), so agreeing with it point by point is no target -- and our DTM at its
   ground points, the measure there (target RMS <= 0.13 m). The water we find against
   its class 9, and what sets its water apart from its ground besides its level (pulse
   density against the tile's, intensity, scan angle). Also the floor of any filter that
   labels points by their height above the true terrain: the file's own ground surface (a
   TIN of its ground points) with a 0.1 m band, against the file's classes.
2. ``MixedConifer.laz`` (90 x 90 m, 37,657 points, lidR's per-point ``treeID`` crowns of
   206 trees -- an algorithm's segmentation, not field truth): our trees against those
   crowns (position = the crown's highest point, height = its z; the tile is normalised).
3. Speed: ``reconstruct lidar`` (ground filter included) on a 1 ha tile cut from
   Topography, in seconds and as a ratio to the time to read that tile (target <= 10 s).
4. Simulation against reality: a stand grown from MixedConifer's crowns (positions,
   heights, crown radii, and each crown's displacement from its top), with what those
   crowns leave out measured on the tile's own points (unlisted small trees in the gaps,
   shrubs: :func:`vegetation_not_listed`), flown by ``scanamp capture lidar``
   (riegl-lms-q560) at the survey's pulse density with two receivers (the preset's full
   waveform, and a discrete one: 4 returns 2.7 m apart), and by the leica-als50-ii
   preset whole (the tile names no sensor);
   point density, share of pulses with several returns, ground share, understory
   share, canopy cover (a diagnostic), vegetation height P50/P95 and tree detection F
   side by side (the real tile holds first returns only -- its number_of_returns still
   says how many the pulse had -- so the simulated survey is compared by its first
   returns too).

The data are read from ``$SCANAMP_REAL_DATA`` or ``../shared/data/real`` beside the
repository (or beside its worktree folder); without them each part says so and is skipped.
"""

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
_CANDIDATES = [os.environ.get("SCANAMP_REAL_DATA"), ROOT.parent / "shared" / "data" / "real",
               ROOT.parents[1] / "shared" / "data" / "real"]
REAL = next((Path(p) for p in _CANDIDATES if p and (Path(p) / "lidar").is_dir()),
            ROOT.parent / "shared" / "data" / "real")
LIDAR = REAL / "lidar"


def _xyz(p):
    return np.column_stack([p["x"], p["y"], p["z"]])


def topography():
    from scipy.interpolate import LinearNDInterpolator

    from core.io.las import read_las
    from reconstruct.lidar import LidarReconConfig, reconstruct_points

    pts, _ = read_las(LIDAR / "Topography.laz")
    ref = pts.pop("classification")
    g_ref = ref == 2
    water = ref == 9
    res = reconstruct_points(pts, config=LidarReconConfig())  # no classes: CSF decides
    g = res.ground
    total = np.mean(g != g_ref)
    dry = ~water
    total_dry = np.mean(g[dry] != g_ref[dry])
    t1 = np.mean(~g[g_ref])
    t2 = np.mean(g[~g_ref])
    xyz = _xyz(pts)
    dz = res.dtm.sample(xyz[g_ref, 0], xyz[g_ref, 1]) - xyz[g_ref, 2]
    dz = dz[np.isfinite(dz)]
    rms = float(np.sqrt(np.mean(dz ** 2)))
    print(f"   Topography: {len(g)} points, its ground {g_ref.sum()} ({g_ref.mean():.1%}), "
          f"ours {g.sum()} ({g.mean():.1%}); CSF {res.timings['ground_s']:.1f} s")
    print(f"   ground classification total error {total:.1%} (reported; its class 2 is a "
          f"sparse lower envelope); without its {water.sum()} water points "
          f"{total_dry:.1%}; type I {t1:.1%}, type II {t2:.1%}")
    wf = res.water
    print(f"   water found {wf.sum()} points ({np.sum(wf & water)} of its {water.sum()} water, "
          f"{np.sum(wf & g_ref)} of its ground); type II without its water: "
          f"{np.mean(g[~g_ref & dry]):.1%}")
    _water_cues(pts, water, g_ref)
    print(f"   DTM at its ground points: RMS {rms:.3f} m, bias {np.mean(dz):+.3f} m, median "
          f"{np.median(dz):+.3f} m, {np.sum(np.abs(dz) > 1)} beyond 1 m "
          f"(target RMS <= 0.13 m) {'PASS' if rms <= 0.13 else 'MISS'}")
    _held_out(xyz, g, g_ref)
    c = xyz[g_ref, :2].mean(axis=0)
    h = xyz[:, 2] - LinearNDInterpolator(xyz[g_ref, :2] - c, xyz[g_ref, 2])(xyz[:, :2] - c)
    band = np.abs(np.nan_to_num(h, nan=99.0)) < 0.1
    print(f"   floor: the file's own ground surface with a 0.1 m band labels "
          f"{np.mean(band != g_ref):.1%} of the points unlike the file "
          f"({np.mean(band[dry] != g_ref[dry]):.1%} without water): points it calls "
          f"unclassified lie on its ground")


def _water_cues(pts, water, g_ref, r=5.0):
    """What sets the file's water apart from its ground, besides its level: the pulse
    density (first returns within r) against the tile's median, where water's absorption
    in the near infrared would leave voids; intensity; scan angle."""
    from scipy.spatial import cKDTree

    xy = _xyz(pts)[:, :2]
    xy = xy - xy.min(axis=0)
    first = pts["return_number"] == 1
    dens = np.array([len(n) for n in cKDTree(xy[first]).query_ball_point(xy, r)]) / (np.pi * r * r)
    med = np.median(dens)
    cue = {"pulse density / tile median": dens / med, "intensity": pts["intensity"],
           "scan angle (deg)": pts["scan_angle"]}
    for k, v in cue.items():
        v = np.asarray(v, np.float64)
        w5, w50, w95 = np.percentile(v[water], [5, 50, 95])
        g5, g50, g95 = np.percentile(v[g_ref], [5, 50, 95])
        print(f"   its water's {k}: median {w50:.2f} (5-95 % {w5:.2f}-{w95:.2f}); its ground's "
              f"{g50:.2f} ({g5:.2f}-{g95:.2f})")


def _held_out(xyz, g, g_ref, seed=0):
    """The DTM where our ground does not simply pass through the file's: from our ground
    less a random half of the file's ground, at that half (the DTM at the file's ground
    points is small whenever we call them ground, whatever else we call ground). Its
    bias says whether our other ground lies above the file's (low vegetation) or below."""
    from reconstruct.lidar.rasters import dtm_from_ground

    half = g_ref & (np.random.default_rng(seed).random(len(g_ref)) < 0.5)
    lo, hi = xyz[:, :2].min(axis=0), xyz[:, :2].max(axis=0)
    out = []
    for src in (g_ref, g):
        dz = (dtm_from_ground(xyz[src & ~half], bounds=(*lo, *hi), res=0.5)
              .sample(xyz[half, 0], xyz[half, 1]) - xyz[half, 2])
        dz = dz[np.isfinite(dz)]
        out.append((float(np.sqrt(np.mean(dz ** 2))), float(np.mean(dz))))
    print(f"   held out: a DTM from our ground less half of its ground, at that half: RMS "
          f"{out[1][0]:.3f} m, bias {out[1][1]:+.3f} m (from its own other half: "
          f"{out[0][0]:.3f} m, {out[0][1]:+.3f} m)")


def _tree_ids(pts):
    """MixedConifer's ``treeID`` with lidR's NA (points in no crown) as 0.

    lidR writes NA as the extra-bytes ``no_data`` value, DBL_MAX (1.8e308): taken as an id,
    those 8,296 points (22 %: ground, shrubs, gaps) made one 30 m "tree" with a 50 m crown.
    """
    tid = np.asarray(pts["treeID"], np.float64)
    return np.where(np.isfinite(tid) & (tid < 1e300), tid, 0.0)


def mixed_conifer_reference(pts):
    """(n, 3) ``x, y, height`` of each treeID crown's highest point, crown radii (n,) and
    (n, 2) crown displacements (the centroid of the crown's convex hull from its top).

    The radius is half the crown width as forest inventories measure it (FIA; Bechtold
    2004): the mean of the crown's longest width and the width across it, here of the
    convex hull of the crown's points. (The radius of a circle of the hull's area is 10 %
    smaller: a crown is rarely round, and its top rarely at its centre.)
    """
    from scipy.spatial import ConvexHull, QhullError

    tid = _tree_ids(pts)
    out, radii, offsets = [], [], []
    for i in np.unique(tid[tid > 0]):
        s = np.flatnonzero(tid == i)
        k = s[np.argmax(pts["z"][s])]
        out.append([pts["x"][k], pts["y"][k], pts["z"][k]])
        xy = np.column_stack([pts["x"][s], pts["y"][s]])
        try:
            hv = xy[ConvexHull(xy).vertices] if len(s) >= 3 else xy
        except QhullError:
            hv = xy
        d = np.linalg.norm(hv[:, None] - hv[None], axis=2)
        a, b = np.unravel_index(np.argmax(d), d.shape)
        longest = d[a, b]
        across = 0.0
        if longest > 0:
            u = (hv[b] - hv[a]) / longest
            across = float(np.ptp(hv @ np.array([-u[1], u[0]])))
        radii.append(max((longest + across) / 4, 0.5))
        # the crown's centre (its hull's centroid) from its top: crowns grow towards gaps
        c = hv.mean(axis=0) if len(hv) < 3 else _polygon_centroid(hv)
        offsets.append(c - out[-1][:2])
    return np.array(out), np.array(radii), np.array(offsets).reshape(-1, 2)


def _polygon_centroid(p):
    """The centroid of polygon ``p (k, 2)``, computed about its vertices' mean: in projected
    coordinates (y ~ 4e6 m) the shoelace products lose metres (the tile's crown offsets came
    out 6.0 m in median, 18.7 m at the 90th percentile, against 0.84 and 1.98 m about the
    mean).

    >>> t = np.arange(12) * np.pi / 6                  # a crown 3 m across a 12-gon ...
    >>> far = np.array([481_349.53, 3_813_010.75])     # ... at MixedConifer's corner (UTM 12N)
    >>> ring = 3 * np.column_stack([np.cos(t), np.sin(t)]) + far
    >>> (_polygon_centroid(ring) - far).round(6).tolist()   # (about the origin: 0.73, 5.75)
    [0.0, 0.0]
    >>> sq = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [1.0, 2.0], [0.0, 2.0]])
    >>> (_polygon_centroid(sq + far) - far).round(6).tolist()   # not the vertices' mean
    [1.0, 1.0]
    """
    m = p.mean(axis=0)
    x, y = p[:, 0] - m[0], p[:, 1] - m[1]
    cr = x * np.roll(y, -1) - np.roll(x, -1) * y
    a = cr.sum() / 2
    if abs(a) < 1e-9:
        return m
    return m + np.array([np.sum((x + np.roll(x, -1)) * cr),
                         np.sum((y + np.roll(y, -1)) * cr)]) / (6 * a)


def _survey_figures(pts, res, ref_trees, area):
    from core.io.las import AsprsClass
    from reconstruct.lidar import height_above, tree_scores

    first = pts["return_number"] == 1
    cls = pts.get("classification")
    ground = (cls == AsprsClass.GROUND) if cls is not None else res.ground
    h = height_above(res.dtm, _xyz(pts))
    veg = h[(~ground) & (h > 2.0)]
    tr = res.trees
    s = tree_scores(ref_trees, np.column_stack([tr["x"], tr["y"], tr["height"]]))
    # canopy cover: the share of the plot's 1 m cells holding a first return over 2 m
    xy = _xyz(pts)[:, :2]
    ij = np.floor(xy - xy.min(axis=0)).astype(np.int64)
    cells = (ij[:, 0].max() + 1) * (ij[:, 1].max() + 1)
    hi = first & (h > 2.0)
    cover = len(np.unique(ij[hi, 0] * (ij[:, 1].max() + 1) + ij[hi, 1])) / cells
    return {"points per m2": len(first) / area, "first returns per m2": first.sum() / area,
            "pulses with several returns": float(np.mean(pts["number_of_returns"][first] > 1)),
            "ground share": float(np.mean(ground)),
            # by height, not by class: the tile's class 2 leaves a third of its ground-level
            # returns unclassed (6.6 % of its points at 0-0.3 m, none with a later return)
            "share within 0.3 m of the DTM": float(np.mean(h < 0.3)),
            "share at 0.3-2 m (understory)": float(np.mean((h >= 0.3) & (h <= 2.0))),
            "shrub cover of the open ground": _shrub_cover(first, h),
            "canopy cover (1 m cells, > 2 m)": float(cover),
            "vegetation height P50 (m)": float(np.percentile(veg, 50)),
            "vegetation height P95 (m)": float(np.percentile(veg, 95)),
            "trees detected": len(tr["x"]), "tree detection F": s["f"],
            "height RMSE (m)": s["height_rmse"]}


def mixed_conifer():
    from core.io.las import read_las
    from reconstruct.lidar import reconstruct_points, tree_scores

    pts, info = read_las(LIDAR / "MixedConifer.laz")
    ref, _, _ = mixed_conifer_reference(pts)
    res = reconstruct_points(pts, crs_wkt=info.crs_wkt)
    tr = res.trees
    s = tree_scores(ref, np.column_stack([tr["x"], tr["y"], tr["height"]]))
    print(f"   MixedConifer: {len(ref)} treeID crowns, {s['detected']} trees found, "
          f"{s['matched']} matched (2.1 m + 0.14 h): detection {s['detection']:.2f}, "
          f"commission {s['commission']:.2f}, F {s['f']:.3f}; height RMSE "
          f"{s['height_rmse']:.2f} m, bias {s['height_bias']:+.2f} m (reported; lidR's "
          f"segmentation is not field truth)")
    return pts, res, ref


def speed():
    from core.io.las import LasWriter, read_las
    from reconstruct.lidar import LidarReconConfig
    from reconstruct.lidar import run as run_lidar

    pts, info = read_las(LIDAR / "Topography.laz")
    x0, y0 = pts["x"].min() + 90, pts["y"].min() + 90
    sel = (pts["x"] >= x0) & (pts["x"] < x0 + 100) & (pts["y"] >= y0) & (pts["y"] < y0 + 100)
    tile = {k: v[sel] for k, v in pts.items() if k != "classification"}
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "tile.laz"
        with LasWriter(src, origin=(x0, y0, 0.0), crs_wkt=info.crs_wkt) as w:
            w.write(tile)
        t_read = min(_timed(lambda: read_las(src)) for _ in range(3))
        times = []
        for k in range(2):
            times.append(_timed(lambda k=k: run_lidar(LidarReconConfig(), src,
                                                      Path(d) / f"out{k}")))
        t = min(times)
    print(f"   reconstruct lidar on a 1 ha tile ({sel.sum()} points, ground filter included): "
          f"{t:.2f} s = {t / t_read:.0f}x the time to read it ({t_read * 1000:.0f} ms); "
          f"target <= 10 s {'PASS' if t <= 10 else 'MISS'}")


def _timed(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def _shrub_crown_area():
    """The mean crown area of the shrubs :func:`data_synth.forest.build_forest` grows:
    heights uniform on ``SHRUB_HEIGHT`` (0.5-2.5 m), crown radius 0.4 x height, so
    pi 0.16 E[h^2] = pi 0.16 (hi^3 - lo^3) / (3 (hi - lo))."""
    from data_synth.forest import SHRUB_HEIGHT

    lo, hi = SHRUB_HEIGHT
    return np.pi * 0.16 * (hi ** 3 - lo ** 3) / (3.0 * (hi - lo))


def _shrub_cover(first, h):
    """The share of the first returns at 0.3-2 m above the DTM among those under 2 m."""
    low = first & (h <= 2.0)
    return float(np.sum(low & (h > 0.3)) / max(low.sum(), 1))


def _cell_tops(xyz, h):
    """The highest ``h`` per 1 m cell of the points' extent (-inf where none)."""
    ij = np.floor(xyz[:, :2] - xyz[:, :2].min(axis=0)).astype(np.int64)
    top = np.full(tuple(ij.max(axis=0) + 1), -np.inf)
    np.maximum.at(top, (ij[:, 0], ij[:, 1]), h)
    return top


def vegetation_not_listed(pts, res, species):
    """What the tile's crowns (its inventory) leave out, measured on the tile's own points
    as a practitioner would before growing a stand from it. On a 1 m grid of the highest
    return per cell (heights above the survey's DTM):

    - unlisted trees: the cells where no ``treeID`` point lies but the top is over 2 m
      (their cover); their heights, the highest cell of each 8-connected patch of such
      cells (one patch ~ one small tree the segmentation missed); their number per
      hectare, that cover over the mean crown area of trees of those heights
      (``pi (crown_width h)^2`` with the species' crown proportion, the stand's mix);
    - shrubs: the share of the first returns at 0.3-2 m among those under 2 m (the shrub
      cover of the open ground: the pulses that reach under 2 m fall on it at random;
      by cells it would be overstated, a shrub of 1.3 m2 touching several 1 m cells),
      per hectare as ``-ln(1 - cover)`` over a shrub's mean crown area
      (:func:`_shrub_crown_area`): shrubs stand anywhere, so that many cover that share
      of any open patch.

    Returns a dict: ``unlisted`` (1/ha), ``unlisted_height``, ``unlisted_height_sd`` (m),
    ``understory`` (1/ha) and the covers they come from.
    """
    from scipy import ndimage

    from procgen.trees import species_for
    from reconstruct.lidar import height_above

    xyz = _xyz(pts)
    h = height_above(res.dtm, xyz)
    top = _cell_tops(xyz, h)
    ij = np.floor(xyz[:, :2] - xyz[:, :2].min(axis=0)).astype(np.int64)
    crown = np.zeros(top.shape, bool)
    inc = _tree_ids(pts) > 0
    crown[ij[inc, 0], ij[inc, 1]] = True
    gap_veg = np.isfinite(top) & ~crown & (top > 2.0)
    lab, n = ndimage.label(gap_veg, structure=np.ones((3, 3)))
    hmax = np.asarray(ndimage.maximum(top, lab, np.arange(1, n + 1)))
    mu, sd = float(hmax.mean()), float(hmax.std())
    cw2 = np.mean([species_for(s).crown_width ** 2 for s in species])
    crown_area = np.pi * cw2 * (mu ** 2 + sd ** 2)
    cover = float(gap_veg.sum() / top.size)
    shrub_cover = _shrub_cover(pts["return_number"] == 1, h)
    return {"unlisted": cover * 1e4 / crown_area, "unlisted_height": mu,
            "unlisted_height_sd": sd, "unlisted_cover": cover, "unlisted_patches": n,
            "understory": -np.log1p(-shrub_cover) * 1e4 / _shrub_crown_area(),
            "shrub_cover": shrub_cover}


#: The scanners the stand is flown with: the LMS-Q560 with its own receiver (full
#: waveform, echoes 0.6 m apart), with a discrete-return one (the ALS50-II's: 4 returns,
#: 2.7 m apart), and the ALS50-II whole (its beam, pulse, wavelength and mirror too).
#: The tile names no sensor; its returns stop at 4, as those of discrete receivers do.
RECEIVERS = {"waveform": {},
             "discrete": {"detection": "discrete", "min_separation": 2.7, "max_returns": 4},
             "als50-ii": {"preset": "leica-als50-ii"}}


def simulation_vs_reality(real_pts, real_res, ref, *, receivers=None, forest=None,
                          estimate=True):
    """The side-by-side table: the stand grown once, flown with each of ``receivers``
    (name -> LidarCaptureConfig fields over the preset and the tile's density; default
    :data:`RECEIVERS`). ``forest``: ForestConfig fields over the stand's; with
    ``estimate``, the unlisted trees and shrubs measured on the tile
    (:func:`vegetation_not_listed`), else none and 200 shrubs/ha."""
    from acquire.lidar.capture import LidarCaptureConfig
    from core.io.las import read_las
    from core.io.trees import read_tree_table, write_tree_table
    from data_synth.forest import ForestConfig, build_forest, write_forest
    from reconstruct.lidar import reconstruct_points
    from scanamp.methods.lidar import run_lidar_capture

    receivers = RECEIVERS if receivers is None else receivers
    _, radii, offsets = mixed_conifer_reference(real_pts)
    xy = _xyz(real_pts)[:, :2]
    area = float(np.prod(xy.max(axis=0) - xy.min(axis=0)))
    real = _survey_figures(real_pts, real_res, ref, area)
    # a 2 m-tall tree is ground-level in lidR's crowns; the stand starts at 2 m. The
    # tile names no species: a mixed conifer stand of the interior West is ponderosa
    # pine, Douglas-fir and white fir, drawn here in equal shares (seeded)
    species = np.random.default_rng(7).choice(["PIPO", "PSME", "ABCO"], size=len(ref))
    # what the tile shows under 2 m is shrubs (the stand's regeneration is not measured)
    fkw = {"understory": 200.0, "regeneration": 0.0}
    if estimate:
        est = vegetation_not_listed(real_pts, real_res, species)
        print(f"   measured on the tile (what its crowns leave out): {est['unlisted_patches']} "
              f"patches over 2 m in no crown covering {est['unlisted_cover']:.1%} of it, tops "
              f"{est['unlisted_height']:.1f} +- {est['unlisted_height_sd']:.1f} m -> "
              f"{est['unlisted']:.0f} unlisted trees/ha; shrub cover of the open ground "
              f"{est['shrub_cover']:.1%} -> {est['understory']:.0f} shrubs/ha")
        fkw = {k: est[k] for k in ("unlisted", "unlisted_height", "unlisted_height_sd",
                                   "understory")}
        fkw["regeneration"] = 0.0
    fkw.update(forest or {})
    sims, times = {}, {}
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        inv = d / "inventory.csv"
        write_tree_table(inv, {"x": ref[:, 0], "y": ref[:, 1], "height": np.maximum(ref[:, 2], 2),
                               "crown_radius": radii, "crown_dx": offsets[:, 0],
                               "crown_dy": offsets[:, 1], "species": species})
        cfg = ForestConfig(relief=0.0, margin=5.0, crs="EPSG:26912", **fkw)
        t0 = time.perf_counter()
        bundle = build_forest(cfg, inventory=inv, seed=1)
        n_tri = sum(len(o.mesh.triangles) for o in bundle.render_scene.objects)
        write_forest(bundle, d / "scene")
        del bundle
        t_scene = time.perf_counter() - t0
        truth = read_tree_table(d / "scene" / "trees.csv")
        # scored against the trees the inventory lists, as the tile is against its crowns
        listed = np.asarray(truth["listed"]) > 0
        sim_ref = np.column_stack([truth["x"], truth["y"], truth["height"]])[listed]
        for name, rx in receivers.items():
            t0 = time.perf_counter()
            ccfg = LidarCaptureConfig(density=real["first returns per m2"], **rx)
            run_lidar_capture(str(d / "scene"), ccfg, d / name)
            times[name] = time.perf_counter() - t0
            sim_pts, _ = read_las(d / name / "points.laz")
            keep = ((sim_pts["x"] >= xy[:, 0].min()) & (sim_pts["x"] <= xy[:, 0].max())
                    & (sim_pts["y"] >= xy[:, 1].min()) & (sim_pts["y"] <= xy[:, 1].max()))
            if np.all(real_pts["return_number"] == 1):  # the tile keeps first returns only
                keep &= sim_pts["return_number"] == 1
            sim_pts = {k: v[keep] for k, v in sim_pts.items()}
            sims[name] = _survey_figures(sim_pts, reconstruct_points(sim_pts), sim_ref, area)
    flown = "; ".join(f"{n}: " + (", ".join(f"{k} {v}" for k, v in rx.items()) or "the preset's")
                      + f", {times[n]:.0f} s" for n, rx in receivers.items())
    print(f"   simulation against reality: a stand of {int(listed.sum())} listed trees + "
          f"{int((~listed).sum())} unlisted, shrubs {cfg.understory:.0f}/ha (grown "
          f"{t_scene:.0f} s, {n_tri / 1e6:.1f} M triangles), flown at "
          f"{real['first returns per m2']:.2f} pulses/m2 by riegl-lms-q560 unless said "
          f"({flown}); the same 90 x 90 m; first returns only, as the real tile keeps:")
    print(f"   {'':32s} {'real':>9s}" + "".join(f" {n:>10s}" for n in sims))
    for k in real:
        print(f"   {k:32s} {real[k]:9.3f}" + "".join(f" {s[k]:10.3f}" for s in sims.values()))
    return real, sims


def main():
    if not LIDAR.is_dir():
        print(f"   {LIDAR} not found, skipped (a fresh clone has no ../shared)")
        return
    topography()
    pts, res, ref = mixed_conifer()
    speed()
    simulation_vs_reality(pts, res, ref)


if __name__ == "__main__":
    main()
