"""scanamp reconstruct laser CAPTURE --out DIR [--overwrite [--from STAGE]]

Run again into the same folder with ``--overwrite``, only the stages whose options or
inputs changed are recomputed; ``--from STAGE`` forces that stage and the later ones."""

import json
import logging
from pathlib import Path

from reconstruct.laser.pipeline import STAGES, LaserReconConfig
from reconstruct.laser.pipeline import run as run_laser

GROUP = "reconstruct"
NAME = "laser"
HELP = ("calibrate (camera, laser plane, axis) and reconstruct a mesh from a laser capture; "
        "scores it when the capture has ground truth")
CONFIG = LaserReconConfig
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("capture", help="capture folder written by 'scanamp capture laser'")
    p.add_argument("--out", required=True, help="reconstruction folder to write")
    p.add_argument("--from", dest="from_stage", choices=STAGES, default=None,
                   help="re-run from this stage on (" + " -> ".join(STAGES) + "); without it "
                        "a stage whose options and inputs are unchanged is reused from --out")


def run(args, config: LaserReconConfig):
    out = run_laser(config, args.capture, args.out, from_stage=args.from_stage)
    rep = json.loads((Path(out) / "report.json").read_text())
    st = rep.get("stages", {})
    if st.get("reused"):
        log.info("stages reused: %s; ran: %s", ", ".join(st["reused"]),
                 ", ".join(st["ran"]) or "none")
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
