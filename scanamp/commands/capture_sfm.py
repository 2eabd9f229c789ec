"""``scanamp capture sfm SCENE --out DIR``: a camera moved around a scene (orbit rings,
hemisphere or hand-held walk), for structure from motion."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

GROUP = "capture"
NAME = "sfm"
HELP = ("render a structure-from-motion capture: orbit rings, hemisphere or hand-held walk; "
        "writes capture.json and a nerfstudio transforms.json")

log = logging.getLogger(__name__)


def add_arguments(p):
    p.add_argument("scene", help="built-in scene name (object, primitives), scene folder or .toml")
    p.add_argument("--out", required=True, type=Path, help="capture folder to write")
    p.add_argument("--config", type=Path, help="TOML path/camera/sensor settings "
                   "(keys of acquire.capture_sfm.PathConfig; [sensor] table)")
    p.add_argument("--seed", type=int, default=0, help="path jitter and sensor noise seed")
    p.add_argument("--path", choices=("orbit", "hemisphere", "walk"),
                   help="override the config's path kind")
    p.add_argument("--views", type=int, help="override the number of views")


def run(args) -> int:
    from acquire.capture_sfm import capture, path_config_from_toml
    from core.files import read_toml
    from data_synth.scenes import build_scene, scene_names

    data = read_toml(args.config) if args.config else {}
    if args.path:
        data["kind"] = args.path
    if args.views:
        data["views"] = args.views
    cfg = path_config_from_toml(data, path=args.config)
    bundle = build_scene(args.scene)
    ref = {"name": bundle.name, "seed": bundle.seed,
           "path": None if args.scene in scene_names() else str(Path(args.scene).resolve())}
    out = capture(bundle.render_scene, cfg, args.out, rng=np.random.default_rng(args.seed),
                  scene_ref=ref, gt_mesh=bundle.gt_mesh(), seed=args.seed)
    log.info("wrote %s (%d views, %s path)", out, cfg.views, cfg.kind)
    return 0
