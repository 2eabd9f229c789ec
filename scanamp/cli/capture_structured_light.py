"""``scanamp capture structured-light SCENE --out DIR``: a camera and a Gray-code +
phase-shift projector scanning a scene on a turntable, with calibration captures. Options
are :class:`acquire.stereo.rig.SLCaptureConfig` (the stereo rig's tables; the right camera
is the projector)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from acquire.stereo.rig import SLCaptureConfig

GROUP = "capture"
NAME = "structured-light"
HELP = ("render a structured-light capture (Gray code + phase shift from a projector modelled "
        "as an inverse camera) of a scene on a turntable, with board calibration views")
CONFIG = SLCaptureConfig


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="scene folder, built-in name (object, primitives) or .toml spec")
    p.add_argument("--out", required=True, type=Path, help="output capture folder")


def run(args: argparse.Namespace, config: SLCaptureConfig) -> int:
    import numpy as np

    from scanamp.methods import METHODS, scene_for_capture

    bundle = scene_for_capture(args.scene)
    out = METHODS["structured-light"].capture(bundle, config, args.out,
                                              rng=np.random.default_rng(config.seed),
                                              seed=config.seed, scene_path=args.scene)
    logging.getLogger("scanamp").info("wrote %s", out)
    return 0
