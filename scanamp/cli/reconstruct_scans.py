"""scanamp reconstruct scans SCANS... --out DIR [--poses FILE]

Range scans from free viewpoints (range-image PLY, point clouds and meshes, E57 files with
many scans, folders, a ``.conf``) registered to each other with no initial pose and
merged into one surface. ``--poses`` is an optional initial guess, never needed."""

import json
import logging
from pathlib import Path

from reconstruct.scans.pipeline import STAGES, ScansReconConfig
from reconstruct.scans.pipeline import run as run_scans

GROUP = "reconstruct"
NAME = "scans"
HELP = ("register range scans to each other with no initial pose (features, seeded RANSAC, "
        "line-of-sight checks, pose graph, multi-view ICP) and merge them into one mesh")
CONFIG = ScansReconConfig
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("scans", nargs="+", metavar="SCANS",
                   help="scan files (.ply range images, clouds, meshes, .obj, .pcd), folders "
                        "of them, .e57 files, or a scanalyze .conf")
    p.add_argument("--out", required=True, help="reconstruction folder to write")
    p.add_argument("--poses", default=None, metavar="FILE",
                   help="initial guess of the poses (.conf, .aln or poses.json); never needed")
    p.add_argument("--from", dest="from_stage", choices=STAGES, default=None,
                   help="re-run from this stage on (" + " -> ".join(STAGES) + ")")


def run(args, config: ScansReconConfig):
    out = run_scans(config, args.scans, args.out, poses=args.poses,
                    from_stage=args.from_stage)
    rep = json.loads((Path(out) / "report.json").read_text())
    c = rep["counts"]
    log.info("%d of %d scans registered (%d of %d pairs verified, %d pruned) -> %d triangles "
             "in %s", c["registered"], c["scans"], c["pairs_verified"], c["pairs_tried"],
             c["edges_pruned"], c["mesh_triangles"], out)
    for s in rep["scans"]:
        if s["registered"]:
            log.info("  %-32s rms %.3f mm, overlap %.0f %%", s["file"], 1000 * (s["rms"] or 0),
                     100 * s["overlap"])
        else:
            log.info("  %-32s NOT REGISTERED: %s", s["file"], s["reason"])
    return 0
