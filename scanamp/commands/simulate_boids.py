"""``scanamp simulate boids RECIPE [--mesh M.ply] --out DIR``."""

from __future__ import annotations

import dataclasses

NAME = "boids"
GROUP = "simulate"
HELP = ("boids flocking around a mesh (Reynolds steering or Couzin zones); RECIPE is a "
        "shipped name (flock, swarm, torus, parallel) or a TOML file")


def add_arguments(p):
    p.add_argument("recipe", help="shipped recipe name or a TOML file ([boids], [run])")
    p.add_argument("--mesh", help="collider mesh (PLY/OBJ/...); default: the recipe's "
                   "procedural stand-in, if any")
    p.add_argument("--out", required=True, help="output folder (replaced atomically)")
    p.add_argument("--n", type=int, help="number of boids (overrides the recipe)")
    p.add_argument("--steps", type=int, help="number of steps (overrides the recipe)")
    p.add_argument("--seed", type=int, help="random seed (overrides the recipe)")
    p.add_argument("--frame-every", type=int, help="write a frame every this many steps")
    p.add_argument("--no-render", action="store_true", help="skip the animation and plot")
    p.add_argument("--gif", action="store_true", help="animation.gif instead of .mp4")
    p.add_argument("--size", default="640x480", help="animation size WxH (default 640x480)")


def run(args) -> int:
    from core.mesh_io import read_mesh
    from scanamp.boids_run import run_boids
    from simulate.boids import load_recipe
    from simulate.stand_ins import stand_in_mesh

    recipe = load_recipe(args.recipe)
    changes = {}
    for flag, key, lo in (("n", "n", 1), ("steps", "steps", 1), ("seed", "seed", 0),
                          ("frame_every", "frame_every", 1)):
        value = getattr(args, flag)
        if value is not None:
            if value < lo:
                raise ValueError(f"--{flag.replace('_', '-')}: expected an integer >= {lo}, "
                                 f"got {value}")
            changes[key] = value
    recipe = dataclasses.replace(recipe, **changes)
    try:
        w, h = (int(s) for s in args.size.lower().split("x"))
        if w < 16 or h < 16:
            raise ValueError
    except ValueError:
        raise ValueError(f"--size: expected WxH with sides >= 16, got {args.size!r}") from None
    if args.mesh:
        mesh = read_mesh(args.mesh)
        if len(mesh.triangles) == 0:
            raise ValueError(f"--mesh: {args.mesh}: expected a collider mesh with faces, "
                             "got 0 triangles")
    elif recipe.obstacle != "none":
        mesh = stand_in_mesh(recipe.obstacle, recipe.obstacle_size)
    else:
        mesh = None
    run_boids(recipe, args.out, mesh=mesh, render=not args.no_render,
              animation="animation.gif" if args.gif else "animation.mp4", width=w, height=h)
    return 0
