"""``scanamp capture lidar SCENE --preset NAME --out DIR``: a time-of-flight LiDAR survey
(airborne strips, a vehicle's path or terrestrial stations) of a scene, written as
``DIR/points.laz`` (LAS 1.4, the truth as extra bytes), ``DIR/report.json`` and, for
stations, ``DIR/scans.e57``. Options are :class:`acquire.lidar.capture.LidarCaptureConfig`
(``--density 10`` plans the flight; ``--workers 2`` or ``--scheduler tcp://host:8786``
runs the strips in parallel; ``--per-strip`` keeps ``DIR/strips/*.laz``)."""

from __future__ import annotations

from pathlib import Path

from acquire.lidar.capture import LidarCaptureConfig

GROUP = "capture"
NAME = "lidar"
HELP = ("simulate a time-of-flight LiDAR survey (airborne, vehicle, terrestrial) of a scene "
        "into LAS/LAZ (and E57 for stations), with per-point truth")
CONFIG = LidarCaptureConfig


def add_arguments(p):
    p.add_argument("scene", help="built-in scene name, scene folder or .toml")
    p.add_argument("--out", required=True, type=Path, help="survey folder to write")


def run(args, config: LidarCaptureConfig) -> int:
    from scanamp.methods.lidar import run_lidar_capture

    run_lidar_capture(args.scene, config, args.out)
    return 0
