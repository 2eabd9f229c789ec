"""``scanamp reconstruct stereo CAPTURE --out DIR`` (a turntable capture) or
``scanamp reconstruct stereo --left L.png --right R.png --calibration stereo.yaml --out DIR``
(a user's own rectifiable pair)."""

from __future__ import annotations

import argparse
from pathlib import Path

GROUP = "reconstruct"
NAME = "stereo"
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
    p.add_argument("--mode", choices=("auto", "passive", "active"), default="auto",
                   help="which capture images to match (auto: dot-pattern images if present)")
    p.add_argument("--no-compare", action="store_true",
                   help="do not also reconstruct and score the other mode")
    p.add_argument("--block-size", type=int, default=5, help="SGBM window (odd)")
    p.add_argument("--wls", action="store_true", help="WLS disparity filter (ximgproc)")
    p.add_argument("--lr-check", action="store_true",
                   help="left-right consistency: drop disparities the right view disagrees with")
    p.add_argument("--sgbm-mode", choices=("sgbm", "hh", "3way"), default="sgbm",
                   help="SGBM paths: 5 (sgbm), 8 with full DP (hh, ~2.5x slower), 3way")
    p.add_argument("--num-disparities", type=int, default=None,
                   help="search range (multiple of 16); default from the rig's working range")
    p.add_argument("--min-disparity", type=int, default=None)
    p.add_argument("--voxel-size", type=float, default=None, metavar="M",
                   help="TSDF voxel in metres (default: far working distance / 500)")


def run(args: argparse.Namespace) -> int:
    import logging

    from reconstruct.stereo_recon import StereoOptions, run_capture, run_pair

    opts = StereoOptions(mode=args.mode, compare=not args.no_compare, block_size=args.block_size,
                         wls=args.wls, lr_check=args.lr_check, sgbm_mode=args.sgbm_mode,
                         num_disparities=args.num_disparities,
                         min_disparity=args.min_disparity, voxel_size=args.voxel_size)
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
