"""``scanamp capture sfm SCENE --out DIR``: a camera moved around a scene (orbit rings,
hemisphere or hand-held walk), for structure from motion. Options are
:class:`acquire.sfm.capture.SfmCaptureConfig` (``--kind walk --views 40``, or ``--config
sfm.toml`` with the same keys and a ``[sensor]`` table)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from acquire.sfm.capture import SfmCaptureConfig

GROUP = "capture"
NAME = "sfm"
HELP = ("render a structure-from-motion capture: orbit rings, hemisphere or hand-held walk; "
        "writes capture.json and a nerfstudio transforms.json")
CONFIG = SfmCaptureConfig

log = logging.getLogger(__name__)


def add_arguments(p):
    p.add_argument("scene", help="built-in scene name (object, primitives), scene folder or .toml")
    p.add_argument("--out", required=True, type=Path, help="capture folder to write")


def run(args, config: SfmCaptureConfig) -> int:
    from data_synth.scenes import scene_names
    from scanamp.methods import METHODS, scene_for_capture

    bundle = scene_for_capture(args.scene)
    path = None if args.scene in scene_names() else Path(args.scene).resolve()
    out = METHODS["sfm"].capture(bundle, config, args.out,
                                 rng=np.random.default_rng(config.seed), seed=config.seed,
                                 scene_path=path)
    log.info("wrote %s (%d views, %s path)", out, config.views, config.kind)
    return 0
