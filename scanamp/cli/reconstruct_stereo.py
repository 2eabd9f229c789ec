"""``scanamp reconstruct stereo CAPTURE --out DIR`` (a turntable capture) or
``scanamp reconstruct stereo --left L.png --right R.png --calibration stereo.yaml --out DIR``
(a user's own rectifiable pair)."""

from __future__ import annotations

import argparse
from pathlib import Path

from reconstruct.stereo.options import StereoOptions

GROUP = "reconstruct"
NAME = "stereo"
CONFIG = StereoOptions
HELP = ("stereo reconstruction: calibration, rectification, SGBM (+LR check, +WLS), depth, "
        "TSDF fusion and meshing; or disparity/depth/points of one calibrated pair")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("capture", nargs="?", type=Path, default=None,
                   help="stereo capture folder (omit with --left/--right/--calibration)")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--left", type=Path, help="left image of a pair")
    p.add_argument("--right", type=Path, help="right image of a pair")
    p.add_argument("--calibration", type=Path, metavar="stereo.yaml",
                   help="cv2.FileStorage YAML with K1 D1 K2 D2 R T image_size (docs/stereo.md)")
    p.add_argument("--disparity-gt", type=Path, default=None, metavar="GT.npy|.pfm|.png",
                   help="ground-truth disparity (rectified left) to score the pair; 0 = unknown")
    p.add_argument("--disparity-gt-scale", type=float, default=None, metavar="S",
                   help="a PNG ground truth stores disparity x S (default: 256 for 16-bit "
                        "PNGs as KITTI, 1 for 8-bit as Middlebury 2001-2006 full size)")


def run(args: argparse.Namespace, opts) -> int:
    import logging

    from reconstruct.stereo.pair import run_pair
    from reconstruct.stereo.pipeline import run_capture

    pair = [args.left, args.right, args.calibration]
    if args.capture is None:
        if any(x is None for x in pair):
            raise ValueError("expected a CAPTURE folder, or all of --left, --right and "
                             "--calibration")
        out = run_pair(args.left, args.right, args.calibration, args.out, options=opts,
                       disparity_gt=args.disparity_gt,
                       disparity_gt_scale=args.disparity_gt_scale)
    else:
        if any(x is not None for x in pair):
            raise ValueError("--left/--right/--calibration: not with a CAPTURE folder")
        out = run_capture(args.capture, args.out, opts)
    logging.getLogger("scanamp").info("wrote %s", out)
    return 0
