"""scanamp capture laser SCENE --out DIR [--config rig.toml] [--seed N]"""

import logging

import numpy as np

from acquire.capture_laser import capture
from acquire.laser_rig import load_rig
from data_synth.scenes import build_scene

GROUP = "capture"
NAME = "laser"
HELP = ("sheet-of-light scan of a scene on a turntable or linear stage, with the "
        "calibration captures (camera target, laser plane, axis)")
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("scene", help="scene folder, built-in name (e.g. 'object') or .toml spec")
    p.add_argument("--out", required=True, help="capture folder to write")
    p.add_argument("--config", default=None,
                   help="rig TOML ([rig], [sensor], [target] tables; see docs/laser.md)")
    p.add_argument("--seed", type=int, default=0, help="sensor noise / calibration poses seed")
    p.add_argument("--steps", type=int, default=None, help="override rig.steps")
    p.add_argument("--size", default=None, help="override the image size, WIDTHxHEIGHT")
    p.add_argument("--gt-depth", action="store_true",
                   help="also write each frame's ground-truth z-depth (gt/depth_*.npy)")


def run(args):
    over = {}
    if args.steps is not None:
        if args.steps < 1:
            raise ValueError(f"--steps: expected a positive integer, got {args.steps}")
        over["steps"] = args.steps
        over["step_deg"] = 360.0 / args.steps
    if args.size:
        try:
            over["width"], over["height"] = (int(x) for x in args.size.lower().split("x"))
        except ValueError:
            raise ValueError(f"--size: expected WIDTHxHEIGHT, got {args.size!r}") from None
    rig = load_rig(args.config, overrides=over)
    bundle = build_scene(args.scene)
    info = {"path": str(args.scene), "name": bundle.name, "seed": bundle.seed}
    out = capture(bundle.render_scene, rig, args.out, np.random.default_rng(args.seed),
                  scene_info=info, seed=args.seed, gt_depth=args.gt_depth,
                  gt_mesh=bundle.gt_mesh())
    log.info("laser capture of %r: %d frames -> %s", bundle.name, rig.steps, out)
    return 0
