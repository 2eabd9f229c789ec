"""``scanamp reconstruct structured-light CAPTURE --out DIR``."""

from __future__ import annotations

import argparse
from pathlib import Path

GROUP = "reconstruct"
NAME = "structured-light"
HELP = ("structured-light reconstruction: camera-projector calibration, Gray-code + phase "
        "decoding, triangulation with the projector, TSDF fusion and meshing")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("capture", type=Path, help="structured-light capture folder")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--min-contrast", type=float, default=12.0,
                   help="white - black DN below which a pixel is in shadow (default 12)")
    p.add_argument("--voxel-size", type=float, default=None, metavar="M",
                   help="TSDF voxel in metres (default: far working distance / 1000)")


def run(args: argparse.Namespace) -> int:
    import logging

    from reconstruct.sl_recon import SLOptions, run_capture

    out = run_capture(args.capture, args.out, SLOptions(min_contrast=args.min_contrast,
                                                         voxel_size=args.voxel_size))
    logging.getLogger("scanamp").info("wrote %s", out)
    return 0
