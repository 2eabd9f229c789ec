"""The DTM error of a ``lidar-ground`` stand before and after this round's ground options
(docs/lidar.md): the filter with the options of before (``densify_below`` 6 degrees,
``lower_spread`` 0), with the defaults, and the true ground's own DTM, beside the true
ground's coverage (where no pulse reached the floor).

    scanamp study lidar-ground --out OUT --workers 2 --keep
    python docs/render_lidar_ground_gaps.py OUT/work/RUN_ID

Draws ``docs/img/lidar_ground_gaps.png`` and prints the three RMSEs.
"""

import sys
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(run: Path) -> None:
    from scipy.spatial import cKDTree

    from core.io.las import read_las
    from core.io.raster import read_raster
    from data_synth.forest import terrain_height
    from reconstruct.lidar.ground import GroundOptions, classify_ground
    from reconstruct.lidar.rasters import dtm_from_ground
    from scanamp.study.lidar_ground import stand_dtm_errors

    pts, _ = read_las(run / "capture" / "points.laz")
    xyz = np.column_stack([pts["x"], pts["y"], pts["z"]])
    last = pts["return_number"] >= pts["number_of_returns"]
    truth = np.isin(pts["classification"], (2, 11))
    terrain = read_raster(run / "scene" / "dtm.tif")
    bounds = (*xyz[:, :2].min(axis=0), *xyz[:, :2].max(axis=0))
    masks = {"before (densify_below 6, lower_spread 0)":
             classify_ground(xyz, last=last, options=GroundOptions(densify_below=6.0,
                                                                   lower_spread=0.0)),
             "defaults": classify_ground(xyz, last=last),
             "the true ground's own DTM": truth}
    fig, ax = plt.subplots(1, 4, figsize=(22, 5.2))
    for a, (name, m) in zip(ax[:3], masks.items(), strict=True):
        dtm = dtm_from_ground(xyz[m], bounds=bounds, res=0.5)
        xs, ys = dtm.centres()
        X, Y = np.meshgrid(xs, ys)
        e = dtm.values - terrain_height(terrain, X, Y)
        rmse = stand_dtm_errors(dtm, terrain, margin=8.0)["rmse"]
        print(f"{name}: DTM RMSE {rmse:.3f} m")  # noqa: T201
        im = a.imshow(e, origin="lower", cmap="RdBu", vmin=-1, vmax=1,
                      extent=(xs[0], xs[-1], ys[0], ys[-1]))
        a.set_title(f"{name}\nRMSE {rmse:.3f} m over the stand")
        a.set_xlim(0, 40)
        a.set_ylim(0, 40)
    fig.colorbar(im, ax=ax[:3], label="DTM - true terrain (m)", shrink=0.8)
    g = np.arange(0.25, 40, 0.5)
    X, Y = np.meshgrid(g, g)
    d, _ = cKDTree(xyz[truth, :2]).query(np.column_stack([X.ravel(), Y.ravel()]))
    im2 = ax[3].imshow(d.reshape(X.shape), origin="lower", cmap="magma_r", vmin=0, vmax=4,
                       extent=(0, 40, 0, 40))
    ax[3].set_title(f"distance to the nearest true ground point\n{np.mean(d > 2):.1%} of the "
                    "stand > 2 m")
    fig.colorbar(im2, ax=ax[3], label="m", shrink=0.8)
    out = Path(__file__).resolve().parent / "img" / "lidar_ground_gaps.png"
    fig.savefig(out, dpi=70, bbox_inches="tight")
    print(f"wrote {out}")  # noqa: T201


if __name__ == "__main__":
    main(Path(sys.argv[1]))
