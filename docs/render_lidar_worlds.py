"""Figures of docs/lidar.md's worlds and reconstruction sections:

- ``lidar_stand.png``: the built-in ``stand`` (40 x 40 m, spruce and beech, shrubs) coloured
  by part, with pyvista off-screen (EGL), and the five species' architectures side by side;
- ``lidar_reconstruction.png``: a survey of it (RIEGL LMS-Q560, 10 pulses/m²) reconstructed
  with the ground found by the cloth filter: a transect coloured by our class against the
  truth's, and the CHM with the tree tops found and the true stems.

Run: ``PYTHONPATH=. python docs/render_lidar_worlds.py`` (writes docs/img/lidar_*.png).
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

OUT = Path(__file__).resolve().parent / "img"


def _part_mesh(objects):
    from acquire.lidar.labels import PARTS
    from core.meshes import make_mesh, to_pyvista
    from data_synth.forest import PART_COLORS

    vs, fs, cols, n = [], [], [], 0
    for o in objects:
        v, f, _ = o.world_arrays()
        vs.append(v)
        fs.append(f + n)
        c = np.zeros((len(v), 3))
        c[f] = np.array([PART_COLORS[PARTS[p]] for p in o.part_labels])[:, None, :]
        cols.append(c)
        n += len(v)
    mesh = to_pyvista(make_mesh(np.vstack(vs), np.vstack(fs), compute_normals=False))
    mesh.point_data["rgb"] = (np.vstack(cols) * 255).astype(np.uint8)
    return mesh


def stand(bundle) -> Path:
    import pyvista as pv

    from procgen.trees import crown_years, grow_tree, place_tree, species_for

    pl = pv.Plotter(off_screen=True, window_size=(1500, 700), shape=(1, 2), border=False)
    pl.subplot(0, 0)
    pl.add_mesh(_part_mesh(bundle.render_scene.objects), scalars="rgb", rgb=True)
    pl.set_background("white")
    pl.view_isometric()
    pl.camera.elevation = -8
    pl.camera.zoom(1.25)
    pl.subplot(0, 1)

    class _Obj:  # the five architectures, 20 m tall, in a row
        def __init__(self, v, f, p):
            self.v, self.f, self.part_labels = v, f, p

        def world_arrays(self):
            return self.v, self.f, None

    from acquire.lidar.labels import part_code

    lut = np.array([part_code(p) for p in ("trunk", "branch", "leaf")], np.uint8)
    objs = []
    for k, sp in enumerate(("PIAB", "ABCO", "PSME", "PIPO", "FASY")):
        rng = np.random.default_rng(k)
        m = grow_tree(sp, rng=rng, years=crown_years(20.0, species_for(sp).crown_ratio))
        v, f, p = place_tree(m, position=(13.0 * k, 0.0, 0.0), height=20.0, rng=rng)
        objs.append(_Obj(v, f, lut[p]))
    pl.add_mesh(_part_mesh(objs), scalars="rgb", rgb=True)
    pl.view_xz()
    pl.camera.zoom(1.05)
    pl.add_text("PIAB   ABCO   PSME   PIPO   FASY", position="lower_edge", font_size=12,
                color="black")
    path = OUT / "lidar_stand.png"
    pl.screenshot(str(path))
    pl.close()
    return path


def reconstruction(bundle) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acquire.lidar.capture import LidarCaptureConfig
    from core.io.las import read_las
    from core.io.raster import read_raster
    from core.io.trees import read_tree_table
    from data_synth.scenes import write_scene
    from reconstruct.lidar import LidarReconConfig, evaluate_lidar
    from reconstruct.lidar import run as run_lidar
    from scanamp.methods.lidar import run_lidar_capture

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        write_scene(bundle, d / "scene")
        run_lidar_capture(str(d / "scene"), LidarCaptureConfig(density=10.0), d / "survey")
        run_lidar(LidarReconConfig(reclassify=True), d / "survey" / "points.laz", d / "recon")
        truth_pts, _ = read_las(d / "survey" / "points.laz")
        ours, _ = read_las(d / "recon" / "classified.laz")
        chm = read_raster(d / "recon" / "chm.tif")
        found = read_tree_table(d / "recon" / "trees.csv")
        scores = evaluate_lidar(d / "recon", d / "scene")
    t = bundle.trees
    fig = plt.figure(figsize=(13, 6.2))
    gs = fig.add_gridspec(2, 2, width_ratios=[1.6, 1])
    y = truth_pts["y"]
    sel = np.abs(y - np.median(y)) < 3
    for row, (name, cls) in enumerate((("the truth's classes", truth_pts["classification"]),
                                       ("our ground (cloth simulation filter)",
                                        ours["classification"]))):
        ax = fig.add_subplot(gs[row, 0])
        g = cls[sel] == 2
        ax.scatter(truth_pts["x"][sel][~g], truth_pts["z"][sel][~g], s=1, c="#2ca02c",
                   label="not ground")
        ax.scatter(truth_pts["x"][sel][g], truth_pts["z"][sel][g], s=1, c="#8c564b",
                   label="ground")
        ax.set_title(f"a 6 m transect, {name}")
        ax.set_aspect("equal")
        ax.legend(loc="upper right", markerscale=6, fontsize=8)
    ax = fig.add_subplot(gs[:, 1])
    xs, ys = chm.centres()
    im = ax.imshow(chm.values, origin="lower", extent=(xs[0], xs[-1], ys[0], ys[-1]),
                   cmap="Greens")
    fig.colorbar(im, ax=ax, shrink=0.7, label="canopy height (m)")
    ax.plot(t["x"], t["y"], "k+", ms=7, label="true stems")
    ax.plot(found["x"], found["y"], "o", mfc="none", mec="r", label="tops found")
    s = scores["trees"]
    ax.set_title(f"CHM: {s['matched']} of {s['reference']} trees found, F {s['f']:.2f}; "
                 f"DTM RMSE {scores['dtm']['rmse']:.2f} m", fontsize=9)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    path = OUT / "lidar_reconstruction.png"
    fig.savefig(path, dpi=100)
    print("scores", scores)  # noqa: T201
    return path


def main():
    from data_synth.scenes import build_scene

    bundle = build_scene("stand")
    print(stand(bundle))  # noqa: T201
    print(reconstruction(bundle))  # noqa: T201


if __name__ == "__main__":
    main()
