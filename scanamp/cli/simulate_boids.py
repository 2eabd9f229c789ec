"""``scanamp simulate boids RECIPE [--mesh M.ply] --out DIR``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from core.config import Config, option

NAME = "boids"
GROUP = "simulate"
HELP = ("boids flocking around a mesh (Reynolds steering or Couzin zones); RECIPE is a "
        "shipped name (flock, swarm, torus, parallel) or a TOML file")


@dataclass
class BoidsOptions(Config):
    """Options of ``scanamp simulate boids`` (the behaviour is the recipe's)."""

    n: int | None = option(None, range="[1, inf)", help="number of boids (default: the recipe's)")
    steps: int | None = option(None, range="[1, inf)",
                               help="number of steps (default: the recipe's)")
    seed: int | None = option(None, range="[0, inf)", help="random seed (default: the recipe's)")
    frame_every: int | None = option(None, range="[1, inf)",
                                     help="write a frame every this many steps (default: the "
                                          "recipe's)")
    render: bool = option(True, help="render the animation and plot (--no-render: skip them)")
    gif: bool = option(False, help="animation.gif instead of .mp4")
    size: str = option("640x480", unit="px", help="animation size WxH")


CONFIG = BoidsOptions


def add_arguments(p):
    p.add_argument("recipe", help="shipped recipe name or a TOML file ([boids], [run])")
    p.add_argument("--mesh", help="collider mesh (PLY/OBJ/...); default: the recipe's "
                   "procedural stand-in, if any")
    p.add_argument("--out", required=True, help="output folder (replaced atomically)")


def run(args, config: BoidsOptions) -> int:
    from core.io.mesh import read_mesh
    from scanamp.animation.boids import run_boids
    from simulate.boids import load_recipe
    from simulate.stand_ins import stand_in_mesh

    recipe = load_recipe(args.recipe)
    changes = {k: getattr(config, k) for k in ("n", "steps", "seed", "frame_every")
               if getattr(config, k) is not None}
    recipe = dataclasses.replace(recipe, **changes)
    try:
        w, h = (int(s) for s in config.size.lower().split("x"))
        if w < 16 or h < 16:
            raise ValueError
    except ValueError:
        raise ValueError(f"--size: expected WxH with sides >= 16, got {config.size!r}") from None
    if args.mesh:
        mesh = read_mesh(args.mesh)
        if len(mesh.triangles) == 0:
            raise ValueError(f"--mesh: {args.mesh}: expected a collider mesh with faces, "
                             "got 0 triangles")
    elif recipe.obstacle != "none":
        mesh = stand_in_mesh(recipe.obstacle, recipe.obstacle_size)
    else:
        mesh = None
    run_boids(recipe, args.out, mesh=mesh, render=config.render,
              animation="animation.gif" if config.gif else "animation.mp4", width=w, height=h)
    return 0
