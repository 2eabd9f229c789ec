"""``scanamp amplify MESH --recipe NAME|FILE --out DIR [--seed N]``."""

from __future__ import annotations

import logging

NAME = "amplify"
HELP = ("amplify a (reconstructed) mesh with a recipe: displace, refine-terrain, scatter, "
        "sweep, hypertexture, animate")

log = logging.getLogger(__name__)


def add_arguments(p):
    from scanamp.amplify.recipe import recipe_names

    p.add_argument("mesh", help="input mesh file (PLY, OBJ, ...)")
    p.add_argument("--recipe", required=True,
                   help=f"shipped recipe ({', '.join(recipe_names())}) or a TOML file")
    p.add_argument("--out", required=True, help="output folder (replaced atomically)")
    p.add_argument("--seed", type=int, default=None,
                   help="random seed (default: the recipe's seed, else 0)")


def run(args) -> int:
    from scanamp.amplify import run as amplify_run

    if args.seed is not None and args.seed < 0:
        raise ValueError(f"--seed: expected an integer >= 0, got {args.seed}")
    out = amplify_run(args.mesh, args.recipe, args.out, seed=args.seed)
    log.info("wrote %s", out)
    return 0
