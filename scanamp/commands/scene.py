"""scanamp scene NAME|SPEC.toml --out DIR [--seed N]"""

import logging
from dataclasses import dataclass

from core.config import Config, option
from data_synth.scenes import build_scene, scene_names, write_scene

NAME = "scene"
HELP = "build a scene (built-in name or TOML spec) into a scene folder"
log = logging.getLogger("scanamp")


@dataclass
class SceneOptions(Config):
    """Options of ``scanamp scene``."""

    seed: int | None = option(None, range="[0, inf)",
                              help="the scene's seed (default: the spec's own)")


CONFIG = SceneOptions


def add_arguments(p):
    p.add_argument("scene", help=f"built-in scene ({', '.join(scene_names())}) or a .toml spec")
    p.add_argument("--out", required=True, help="output scene folder")


def run(args, config: SceneOptions):
    bundle = build_scene(args.scene, seed=config.seed)
    out = write_scene(bundle, args.out)
    tris = sum(len(m.triangles) for m in bundle.meshes.values())
    log.info("scene %r (seed %d): %d objects, %d triangles -> %s", bundle.name, bundle.seed,
             len(bundle.meshes), tris, out)
    return 0
