"""``scanamp capture stereo SCENE --out DIR``: a stereo rig (optionally with a random-dot
projector) scanning a scene on a turntable, with ChArUco calibration captures. Options
are :class:`acquire.stereo.rig.StereoCaptureConfig` (``--rig.baseline 0.12``, or
``--config rig.toml`` with its tables, docs/stereo.md)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from acquire.stereo.rig import StereoCaptureConfig

GROUP = "capture"
NAME = "stereo"
HELP = ("render a stereo capture (passive pairs, and active pairs with a random-dot projector) "
        "of a scene on a turntable, with board calibration views")
CONFIG = StereoCaptureConfig


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="scene folder, built-in name (object, primitives) or .toml spec")
    p.add_argument("--out", required=True, type=Path, help="output capture folder")


def run(args: argparse.Namespace, config: StereoCaptureConfig) -> int:
    import numpy as np

    from scanamp.methods import METHODS, scene_for_capture

    bundle = scene_for_capture(args.scene, textureless=config.textureless)
    out = METHODS["stereo"].capture(bundle, config, args.out,
                                    rng=np.random.default_rng(config.seed), seed=config.seed,
                                    scene_path=args.scene)
    logging.getLogger("scanamp").info("wrote %s", out)
    return 0
