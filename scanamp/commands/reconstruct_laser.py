"""scanamp reconstruct laser CAPTURE --out DIR"""

import json
import logging
from pathlib import Path

from reconstruct.laser import LaserReconConfig
from reconstruct.laser import run as run_laser

GROUP = "reconstruct"
NAME = "laser"
HELP = ("calibrate (camera, laser plane, axis) and reconstruct a mesh from a laser capture; "
        "scores it when the capture has ground truth")
CONFIG = LaserReconConfig
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("capture", help="capture folder written by 'scanamp capture laser'")
    p.add_argument("--out", required=True, help="reconstruction folder to write")


def run(args, config: LaserReconConfig):
    out = run_laser(config, args.capture, args.out)
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
