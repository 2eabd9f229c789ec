"""``scanamp reconstruct structured-light CAPTURE --out DIR``; options are
:class:`reconstruct.stereo.sl_pipeline.SLOptions`'s (flags, or ``--config FILE.toml``)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from reconstruct.stereo.sl_pipeline import SLOptions

GROUP = "reconstruct"
NAME = "structured-light"
HELP = ("structured-light reconstruction: camera-projector calibration, Gray-code + phase "
        "decoding, triangulation with the projector, TSDF fusion and meshing")
CONFIG = SLOptions


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("capture", type=Path, help="structured-light capture folder")
    p.add_argument("--out", required=True, type=Path, help="output folder")


def run(args: argparse.Namespace, config: SLOptions) -> int:
    from reconstruct.stereo.sl_pipeline import run_capture

    out = run_capture(args.capture, args.out, config)
    logging.getLogger("scanamp").info("wrote %s", out)
    return 0
