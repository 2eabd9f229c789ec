"""``scanamp capture scans SCENE --views N --out DIR``: a sheet-of-light range scanner on a
linear sweep, placed at N viewpoints around and above the scene (no turntable); each scan is
a PLY range grid in the scanner's own frame, the true poses are for evaluation only.
Options are :class:`acquire.scans.capture.ScansCaptureConfig` (``--views 12
--elevation-max-deg 60 --head.standoff 0.4 --head.steps 100 --sensor.read-noise 4``, or
``--config scans.toml`` with ``[head]`` and ``[sensor]`` tables)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from acquire.scans.capture import ScansCaptureConfig

GROUP = "capture"
NAME = "scans"
HELP = ("multi-view range scanning: a sheet-of-light head on a linear sweep at N viewpoints "
        "around and above the scene; writes scans/scan_NN.ply (range grids) and the true "
        "poses (poses.json, poses.conf) for evaluation")
CONFIG = ScansCaptureConfig

log = logging.getLogger(__name__)


def add_arguments(p):
    p.add_argument("scene", help="built-in scene name (e.g. 'object'), scene folder or .toml")
    p.add_argument("--out", required=True, type=Path, help="capture folder to write")


def run(args, config: ScansCaptureConfig) -> int:
    from acquire.scans.capture import capture_scans
    from data_synth.scenes import scene_names
    from scanamp.methods import scene_for_capture

    bundle = scene_for_capture(args.scene)
    path = args.scene if args.scene in scene_names() else str(Path(args.scene).resolve())
    out = capture_scans(bundle.render_scene, config, args.out,
                        np.random.default_rng(config.seed), seed=config.seed,
                        scene_info={"path": path, "name": bundle.name, "seed": bundle.seed},
                        gt_mesh=bundle.gt_mesh())
    log.info("range scans of %r: %d views -> %s", bundle.name, config.views, out)
    return 0
