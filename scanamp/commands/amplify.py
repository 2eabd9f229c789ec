"""``scanamp amplify MESH --recipe NAME|FILE --out DIR [--seed N]``."""

from __future__ import annotations

import logging
from dataclasses import dataclass

from core.config import Config, option

NAME = "amplify"
HELP = ("amplify a (reconstructed) mesh with a recipe: displace, refine-terrain, scatter, "
        "sweep, hypertexture, animate")

log = logging.getLogger(__name__)


@dataclass
class AmplifyOptions(Config):
    """Options of ``scanamp amplify`` (the steps and their parameters are the recipe's)."""

    seed: int | None = option(None, range="[0, inf)",
                              help="random seed (default: the recipe's seed, else 0)")
    up: tuple[float, float, float] | None = option(
        None, help="up in the mesh's frame, x,y,z (none: from a camera model beside the mesh "
                   "- transforms.json or sparse/ - else from the mesh's ground and walls)")


CONFIG = AmplifyOptions


def add_arguments(p):
    from scanamp.amplify.recipe import recipe_names

    p.add_argument("mesh", help="input mesh file (PLY, OBJ, ...)")
    p.add_argument("--recipe", required=True,
                   help=f"shipped recipe ({', '.join(recipe_names())}) or a TOML file")
    p.add_argument("--out", required=True, help="output folder (replaced atomically)")


def run(args, config: AmplifyOptions) -> int:
    from scanamp.amplify import run as amplify_run

    out = amplify_run(args.mesh, args.recipe, args.out, seed=config.seed, up=config.up)
    log.info("wrote %s", out)
    return 0
