"""scanamp scene NAME|SPEC.toml --out DIR [--seed N]

``scanamp scene forest [--inventory TREES.csv] [--forest.OPTION ...]`` grows a forest stand
(:mod:`data_synth.forest`): from a plot's inventory, or procedurally."""

import logging
from dataclasses import dataclass
from pathlib import Path

from core.config import Config, option
from data_synth.forest import ForestConfig
from data_synth.scenes import build_scene, scene_names, write_scene

NAME = "scene"
HELP = "build a scene (built-in name or TOML spec) into a scene folder"
log = logging.getLogger("scanamp")


@dataclass
class SceneOptions(Config):
    """Options of ``scanamp scene``."""

    seed: int | None = option(None, range="[0, inf)",
                              help="the scene's seed (default: the spec's own)")
    forest: ForestConfig = option(default_factory=ForestConfig,
                                  help="the stand of 'scanamp scene forest' (a spec file's "
                                       "own [forest] table wins over these)")


CONFIG = SceneOptions


def add_arguments(p):
    p.add_argument("scene", help=f"built-in scene ({', '.join(scene_names())}) or a .toml spec")
    p.add_argument("--out", required=True, help="output scene folder")
    p.add_argument("--inventory", type=Path, default=None, metavar="TREES.csv",
                   help="forest: grow the trees of this inventory (columns x, y, height; "
                        "optional dbh, crown_radius, species)")


def run(args, config: SceneOptions):
    from core.validate import InputError

    if args.scene == "forest":
        from data_synth.forest import forest_spec

        spec = forest_spec(config.forest, seed=0 if config.seed is None else config.seed,
                           inventory=None if args.inventory is None
                           else str(args.inventory.resolve()))
        bundle = build_scene(spec)
    elif args.inventory is not None:
        raise InputError("only the forest scene takes an inventory", field="--inventory")
    else:
        bundle = build_scene(args.scene, seed=config.seed)
    out = write_scene(bundle, args.out)
    tris = sum(len(m.triangles) for m in bundle.meshes.values())
    log.info("scene %r (seed %d): %d objects, %d triangles -> %s", bundle.name, bundle.seed,
             len(bundle.meshes), tris, out)
    trees = getattr(bundle, "trees", None)
    if trees:
        log.info("%d trees (truth in %s/trees.csv, terrain in %s/dtm.tif)", len(trees["x"]),
                 out, out)
    return 0
