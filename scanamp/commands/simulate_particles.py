"""``scanamp simulate particles RECIPE [--mesh M.ply] --out DIR``.

Also the shared options and runner of ``scanamp simulate cloth``.
"""

from __future__ import annotations

import sys

GROUP = "simulate"
NAME = "particles"
HELP = "run a particles recipe (shipped name or TOML) and write VTP/.pvd, PLY, MP4 and report.json"


def add_arguments(p):
    from simulate.recipes import RECIPES

    p.add_argument("recipe", help="a shipped recipe (%s) or a TOML file" % ", ".join(RECIPES))
    p.add_argument("--mesh", help="collider / emitter mesh (e.g. a scan); default: a "
                   "procedural stand-in")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--frames", type=int, help="override the recipe's frame count")
    p.add_argument("--seed", type=int, help="override the recipe's seed")
    p.add_argument("--no-render", action="store_true", help="skip the animation")
    p.add_argument("--gif", action="store_true", help="animation.gif instead of .mp4")
    p.add_argument("--size", default="480x360", help="video size WxH (default 480x360)")


def run_kind(kind: str, args) -> int:
    """Run ``args`` as a ``kind`` (particles / cloth) simulation; 1 when it blew up."""
    from scanamp.simulation_run import run_simulation

    try:
        w, h = (int(s) for s in args.size.lower().split("x"))
        if w < 16 or h < 16:
            raise ValueError
    except ValueError:
        raise ValueError(f"--size: expected WxH with sides >= 16, got {args.size!r}") from None
    if args.frames is not None and args.frames < 1:
        raise ValueError(f"--frames: expected an integer >= 1, got {args.frames}")
    report = run_simulation(kind, args.recipe, args.out, mesh_path=args.mesh,
                            frames=args.frames, render=not args.no_render, width=w, height=h,
                            seed=args.seed,
                            animation="animation.gif" if args.gif else "animation.mp4")
    if report["status"] != "ok":
        sys.stderr.write(f"error: {report['error']} (frames so far in {args.out})\n")
        return 1
    return 0


def run(args) -> int:
    return run_kind("particles", args)
