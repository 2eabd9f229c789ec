"""``scanamp reconstruct sfm CAPTURE_OR_IMAGE_FOLDER --out DIR``: pycolmap on the CPU, then a
dense surface from rectified SGBM depth maps fused in a TSDF."""

from __future__ import annotations

import logging
from pathlib import Path

GROUP = "reconstruct"
NAME = "sfm"
HELP = ("structure from motion on a capture or a folder of photos (pycolmap, CPU) with a "
        "dense surface; writes the COLMAP model, points.ply, mesh.ply and report.json")

log = logging.getLogger(__name__)


def add_arguments(p):
    p.add_argument("input", type=Path, help="SfM capture folder (capture.json) or image folder")
    p.add_argument("--out", required=True, type=Path, help="reconstruction folder to write")
    p.add_argument("--camera", help="intrinsics MODEL:params in COLMAP's order, e.g. "
                   "SIMPLE_RADIAL:800,320,240,0, or a camera.yaml from scanamp calibrate "
                   "camera (default: the capture's nominal camera, else EXIF, else estimated)")
    p.add_argument("--mapper", choices=("incremental", "global"), default="incremental")
    p.add_argument("--matcher", choices=("auto", "exhaustive", "sequential", "spatial"),
                   default="auto")
    p.add_argument("--no-dense", action="store_true", help="sparse reconstruction only")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=-1, help="threads (-1 = all cores)")


def run(args) -> int:
    from reconstruct.sfm import SfmConfig, run

    cfg = SfmConfig(camera=args.camera, mapper=args.mapper, matcher=args.matcher,
                    dense=not args.no_dense, seed=args.seed, num_threads=args.threads)
    res = run(cfg, args.input, args.out)
    if not res.ok:
        raise RuntimeError(res.message)
    rep = res.report
    line = (f"registered {rep['registered']}/{rep['num_images']} images, "
            f"{rep['sparse']['num_points']} points, reprojection "
            f"{rep['sparse']['mean_reprojection_error_px']:.3f} px")
    poses = rep.get("metrics", {}).get("poses")
    if poses:
        line += (f"; rotation error {poses['rotation_error_deg']['mean']:.4f} deg, "
                 f"ATE {100 * poses.get('ate_fraction_of_scene', float('nan')):.4f}% of scene")
    mesh = rep.get("metrics", {}).get("mesh")
    if mesh:
        line += f"; mesh F-score {mesh['fscore']:.3f}"
    log.info("%s -> %s", line, res.out_dir)
    return 0
