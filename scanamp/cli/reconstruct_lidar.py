"""scanamp reconstruct lidar POINTS.laz --out DIR [--reclassify]"""

import json
import logging
from pathlib import Path

from reconstruct.lidar.pipeline import LidarReconConfig
from reconstruct.lidar.pipeline import run as run_lidar

GROUP = "reconstruct"
NAME = "lidar"
HELP = ("ground (cloth simulation filter), DTM and CHM GeoTIFFs, and individual trees of an "
        "airborne LiDAR survey (LAS/LAZ, simulated or real)")
CONFIG = LidarReconConfig
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("points", type=Path, metavar="POINTS.laz",
                   help="the survey (.las or .laz); its coordinates and CRS are kept")
    p.add_argument("--out", required=True, help="reconstruction folder to write")


def run(args, config: LidarReconConfig):
    out = run_lidar(config, args.points, args.out)
    rep = json.loads((Path(out) / "report.json").read_text())
    g = rep["ground"]
    log.info("%d points, %.1f%% ground (%s); %d trees -> %s", rep["points"], 100 * g["share"],
             "classified here" if g["reclassified"] else "the file's class",
             rep["trees"]["count"], out)
    return 0
