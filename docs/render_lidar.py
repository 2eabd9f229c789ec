"""Figures of docs/lidar.md: an airborne survey of the built-in forest stand (RIEGL
LMS-Q560 at 300 m, 10 pts/m2, 5 x 5 sub-rays), a 10 m transect seen from the side,
coloured by return number and by class; and the multiple-return share against the beam
divergence over the same stand.

Run: ``PYTHONPATH=. python docs/render_lidar.py`` (writes docs/img/lidar_*.png).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent / "img"


def _survey(bundle, divergence=None):
    from acquire.lidar.capture import LidarCaptureConfig
    from core.io.las import read_las
    from scanamp.methods.lidar import run_lidar_capture

    cfg = LidarCaptureConfig(preset="riegl-lms-q560", density=10.0, divergence=divergence)
    with tempfile.TemporaryDirectory() as tmp:
        r = run_lidar_capture("forest", cfg, Path(tmp) / "s", bundle=bundle)
        pts, _ = read_las(Path(tmp) / "s" / "points.laz")
    return r, pts


def main():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from data_synth.scenes import build_scene

    bundle = build_scene("forest")
    report, p = _survey(bundle)
    o = bundle.origin if hasattr(bundle, "origin") else np.zeros(3)
    y = p["y"] - o[1]
    sel = (y > 35) & (y < 45)
    x, z = p["x"][sel] - o[0], p["z"][sel] - o[2]
    fig, ax = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    rn = p["return_number"][sel]
    for k, c in ((1, "#1f77b4"), (2, "#ff7f0e"), (3, "#2ca02c"), (4, "#d62728")):
        m = rn == k if k < 4 else rn >= 4
        ax[0].scatter(x[m], z[m], s=1.5, c=c, label=f"return {k}{'+' if k == 4 else ''}")
    ax[0].legend(loc="upper right", markerscale=6, fontsize=8)
    ax[0].set_title("LMS-Q560 at 300 m, 10 pts/m2, 5x5 sub-rays: a 10 m transect by return")
    cl = p["classification"][sel]
    names = {2: ("ground", "#8c564b"), 3: ("low veg.", "#bcbd22"), 4: ("medium veg.", "#98df8a"),
             5: ("high veg.", "#2ca02c"), 6: ("building", "#7f7f7f"), 11: ("road", "k")}
    for k, (name, c) in names.items():
        m = cl == k
        if m.any():
            ax[1].scatter(x[m], z[m], s=1.5, c=c, label=name)
    ax[1].legend(loc="upper right", markerscale=6, fontsize=8)
    ax[1].set_title("by class (from the per-point truth and the height above the ground)")
    ax[1].set_xlabel("x (m)")
    for a in ax:
        a.set_ylabel("z (m)")
        a.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(OUT / "lidar_transect.png", dpi=110)
    divs = [0.1, 0.25, 0.5, 1.0, 2.0, 4.0]
    shares = [_survey(bundle, d)[0]["multiple_return_share"] for d in divs]
    fig, ax = plt.subplots(figsize=(5, 3.2))
    ax.plot(divs, np.array(shares) * 100, "o-")
    ax.set_xscale("log")
    ax.set_xlabel("beam divergence (mrad)")
    ax.set_ylabel("pulses with several returns (%)")
    ax.set_title("the forest stand at 300 m, 10 pts/m2")
    fig.tight_layout()
    fig.savefig(OUT / "lidar_divergence.png", dpi=110)
    print("divergence", divs, "share", [round(s, 4) for s in shares])  # noqa: T201
    print("report", {k: report[k] for k in ("pulses", "points", "multiple_return_share",  # noqa: T201
                                              "density_first_per_m2", "by_class", "by_part")})


if __name__ == "__main__":
    main()
