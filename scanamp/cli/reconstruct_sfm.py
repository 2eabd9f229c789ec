"""``scanamp reconstruct sfm CAPTURE_OR_IMAGE_FOLDER --out DIR``: pycolmap on the CPU (or
known cameras, ``--cameras``), then PatchMatch multi-view stereo, fusion and a trimmed
Poisson surface (:mod:`reconstruct.mvs.pipeline`). The work is named stages (features -> matches ->
sparse -> dense -> fuse -> mesh -> evaluate): run again into the same folder with
``--overwrite``, only the stages whose options or inputs changed are recomputed;
``--from STAGE`` forces that stage and the later ones.

Options are :class:`reconstruct.sfm.pipeline.SfmConfig`'s (flags, or ``--config FILE.toml``)."""

from __future__ import annotations

import logging
from pathlib import Path

from reconstruct.sfm.pipeline import STAGES, SfmConfig

GROUP = "reconstruct"
NAME = "sfm"
HELP = ("structure from motion on a capture or a folder of photos (pycolmap, CPU; or known "
        "cameras) with PatchMatch multi-view stereo; writes the COLMAP model, points.ply, "
        "dense/ depth maps, fused.ply, mesh.ply and report.json")
CONFIG = SfmConfig

log = logging.getLogger(__name__)


def add_arguments(p):
    p.add_argument("input", type=Path, help="SfM capture folder (capture.json) or a folder of "
                                            "photos (JPEG, PNG, TIFF; EXIF orientation applied)")
    p.add_argument("--out", required=True, type=Path, help="reconstruction folder to write")
    p.add_argument("--from", dest="from_stage", choices=STAGES, default=None,
                   help="re-run from this stage on (" + " -> ".join(STAGES) + "); without it "
                        "a stage whose options and inputs are unchanged is reused from --out")


def run(args, config: SfmConfig) -> int:
    from reconstruct.sfm.pipeline import run

    res = run(config, args.input, args.out, from_stage=args.from_stage)
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
    dense = rep.get("dense")
    if dense and dense.get("views"):
        line += (f"; fused depth on {100 * dense['min_fused_coverage']:.0f}% or more of each "
                 f"view's pixels")
    mesh = rep.get("metrics", {}).get("mesh")
    if mesh:
        line += f"; mesh F-score {mesh['fscore']:.3f}"
    log.info("%s -> %s", line, res.out_dir)
    return 0
