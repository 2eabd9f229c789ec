"""scanamp reconstruct laser CAPTURE --out DIR"""

import json
import logging
from pathlib import Path

from reconstruct.laser import DEFAULT_DETECTOR, LaserReconConfig
from reconstruct.laser import run as run_laser
from reconstruct.meshing import MeshingOptions
from reconstruct.stripe import DETECTORS

GROUP = "reconstruct"
NAME = "laser"
HELP = ("calibrate (camera, laser plane, axis) and reconstruct a mesh from a laser capture; "
        "scores it when the capture has ground truth")
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("capture", help="capture folder written by 'scanamp capture laser'")
    p.add_argument("--out", required=True, help="reconstruction folder to write")
    p.add_argument("--detector", default=DEFAULT_DETECTOR, choices=DETECTORS,
                   help=f"sub-pixel stripe detector (default {DEFAULT_DETECTOR})")
    p.add_argument("--threshold", type=float, default=20.0,
                   help="minimum stripe peak, 8-bit units")
    p.add_argument("--depth", type=int, default=9, help="Poisson octree depth")
    p.add_argument("--no-eval", action="store_true", help="skip the ground-truth evaluation")
    p.add_argument("--tau", type=float, default=0.5, help="F-score threshold in mm")


def run(args):
    cfg = LaserReconConfig(detector=args.detector, threshold=args.threshold,
                           meshing=MeshingOptions(depth=args.depth, density_quantile=0.03,
                                                  trim_distance=0.002),
                           evaluate=not args.no_eval, tau=args.tau / 1000.0)
    out = run_laser(cfg, args.capture, args.out)
    rep = json.loads((Path(out) / "report.json").read_text())
    c = rep["counts"]
    log.info("%d stripe points from %d frames -> %d triangles; camera RMS %.3f px -> %s",
             c["stripe_points"], c["frames"], c["mesh_triangles"],
             rep["calibration"]["camera"]["rms_px"], out)
    ev = rep.get("evaluation")
    if ev:
        s = ev["surface"]
        log.info("F-score@%.2gmm %.3f (P %.3f R %.3f); depth RMS %.3g mm vs predicted %.3g mm",
                 1000 * s["tau"], s["fscore"], s["precision"], s["recall"],
                 1000 * (ev.get("depth_error", {}).get("rms_m") or float("nan")),
                 1000 * (ev.get("depth_error", {}).get("predicted_rms_m") or float("nan")))
    return 0
