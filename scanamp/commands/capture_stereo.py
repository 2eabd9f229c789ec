"""``scanamp capture stereo SCENE --out DIR``: a stereo rig (optionally with a random-dot
projector) scanning a scene on a turntable, with ChArUco calibration captures."""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

GROUP = "capture"
NAME = "stereo"
HELP = ("render a stereo capture (passive pairs, and active pairs with a random-dot projector) "
        "of a scene on a turntable, with board calibration views")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="scene folder, built-in name (object, primitives) or .toml spec")
    p.add_argument("--out", required=True, type=Path, help="output capture folder")
    p.add_argument("--config", type=Path, default=None, metavar="RIG.toml",
                   help="rig settings (see docs/stereo.md); default: the built-in rig")
    p.add_argument("--seed", type=int, default=0, help="calibration poses, dots, sensor noise")
    p.add_argument("--textureless", action="store_true",
                   help="give every object a constant material (passive stereo fails there)")
    p.add_argument("--object", default=None,
                   help="name of the scanned object in the scene (its mesh sets the evaluation "
                        "scale); default: 'object' when the scene has one")


def load_scene_for_capture(scene: str, textureless: bool):
    from data_synth.scenes import build_scene

    bundle = build_scene(scene)
    if textureless:
        spec = copy.deepcopy(bundle.spec)
        for obj in spec.get("objects", []):
            mat = obj.get("material", {})
            obj["material"] = {"kind": "constant", "albedo": mat.get("albedo", [0.7, 0.7, 0.7])}
        bundle = build_scene(spec)
    return bundle


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from acquire.capture_stereo import capture
    from acquire.stereo_rig import load_rig

    rig = load_rig(args.config)
    bundle = load_scene_for_capture(args.scene, args.textureless)
    names = [o.name for o in bundle.render_scene.objects]
    obj = args.object or ("object" if "object" in names else None)
    if obj is not None and obj not in names:
        raise ValueError(f"--object: expected one of {', '.join(names)}, got {obj!r}")
    info = {"path": str(args.scene), "name": bundle.name, "seed": bundle.seed,
            "textureless": bool(args.textureless)}
    out = capture(bundle.render_scene, rig, args.out, np.random.default_rng(args.seed),
                  scene_info=info, seed=args.seed, object_name=obj)
    import logging

    logging.getLogger("scanamp").info("wrote %s", out)
    return 0
