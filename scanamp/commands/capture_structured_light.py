"""``scanamp capture structured-light SCENE --out DIR``: a camera and a Gray-code +
phase-shift projector scanning a scene on a turntable, with calibration captures."""

from __future__ import annotations

import argparse
from pathlib import Path

GROUP = "capture"
NAME = "structured-light"
HELP = ("render a structured-light capture (Gray code + phase shift from a projector modelled "
        "as an inverse camera) of a scene on a turntable, with board calibration views")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="scene folder, built-in name (object, primitives) or .toml spec")
    p.add_argument("--out", required=True, type=Path, help="output capture folder")
    p.add_argument("--config", type=Path, default=None, metavar="RIG.toml",
                   help="rig settings (docs/stereo.md); the right camera is the projector")
    p.add_argument("--seed", type=int, default=0, help="calibration poses and sensor noise")
    p.add_argument("--object", default=None,
                   help="name of the scanned object (default: 'object' when present)")


def run(args: argparse.Namespace) -> int:
    import logging

    import numpy as np

    from acquire.capture_sl import capture
    from acquire.stereo_rig import load_rig
    from data_synth.scenes import build_scene

    rig = load_rig(args.config)
    bundle = build_scene(args.scene)
    names = [o.name for o in bundle.render_scene.objects]
    obj = args.object or ("object" if "object" in names else None)
    if obj is not None and obj not in names:
        raise ValueError(f"--object: expected one of {', '.join(names)}, got {obj!r}")
    out = capture(bundle.render_scene, rig, args.out, np.random.default_rng(args.seed),
                  scene_info={"path": str(args.scene), "name": bundle.name,
                              "seed": bundle.seed}, seed=args.seed, object_name=obj)
    logging.getLogger("scanamp").info("wrote %s", out)
    return 0
