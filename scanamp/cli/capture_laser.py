"""``scanamp capture laser SCENE --out DIR``: a sheet-of-light scan with its calibration
captures. Options are :class:`acquire.laser.rig.LaserCaptureConfig` (``--rig.steps 90``,
``--sensor.read-noise 4``, or ``--config rig.toml`` with ``[rig]``, ``[sensor]``,
``[target]`` tables)."""

import logging

import numpy as np

from acquire.laser.rig import LaserCaptureConfig

GROUP = "capture"
NAME = "laser"
HELP = ("sheet-of-light scan of a scene on a turntable or linear stage, with the "
        "calibration captures (camera target, laser plane, axis)")
CONFIG = LaserCaptureConfig
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("scene", help="scene folder, built-in name (e.g. 'object') or .toml spec")
    p.add_argument("--out", required=True, help="capture folder to write")


def run(args, config: LaserCaptureConfig) -> int:
    from scanamp.methods import METHODS, scene_for_capture

    bundle = scene_for_capture(args.scene)
    out = METHODS["laser"].capture(bundle, config, args.out,
                                   rng=np.random.default_rng(config.seed), seed=config.seed,
                                   scene_path=args.scene)
    log.info("laser capture of %r: %d frames -> %s", bundle.name, config.rig.steps, out)
    return 0
