"""``scanamp simulate particles RECIPE [--mesh M.ply] --out DIR``.

Also the shared options and runner of ``scanamp simulate cloth``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

from core.config import Config, option

GROUP = "simulate"
NAME = "particles"
HELP = "run a particles recipe (shipped name or TOML) and write VTP/.pvd, PLY, MP4 and report.json"


@dataclass
class SimulationOptions(Config):
    """Options of ``scanamp simulate particles`` and ``scanamp simulate cloth`` (the physics
    is the recipe's)."""

    frames: int | None = option(None, range="[1, inf)",
                                help="frame count (default: the recipe's)")
    seed: int | None = option(None, range="[0, inf)", help="random seed (default: the recipe's)")
    render: bool = option(True, help="render the animation (--no-render: skip it)")
    gif: bool = option(False, help="animation.gif instead of .mp4")
    size: str = option("480x360", unit="px", help="video size WxH")


CONFIG = SimulationOptions


def add_arguments(p):
    from simulate.recipes import RECIPES

    p.add_argument("recipe", help="a shipped recipe (%s) or a TOML file" % ", ".join(RECIPES))
    p.add_argument("--mesh", help="collider / emitter mesh (e.g. a scan); default: a "
                   "procedural stand-in")
    p.add_argument("--out", required=True, help="output folder")


def run_kind(kind: str, args, config: SimulationOptions) -> int:
    """Run ``args`` as a ``kind`` (particles / cloth) simulation; 1 when it blew up."""
    from scanamp.animation.simulation import run_simulation

    try:
        w, h = (int(s) for s in config.size.lower().split("x"))
        if w < 16 or h < 16:
            raise ValueError
    except ValueError:
        raise ValueError(f"--size: expected WxH with sides >= 16, got {config.size!r}") from None
    report = run_simulation(kind, args.recipe, args.out, mesh_path=args.mesh,
                            frames=config.frames, render=config.render, width=w, height=h,
                            seed=config.seed,
                            animation="animation.gif" if config.gif else "animation.mp4")
    if report["status"] != "ok":
        sys.stderr.write(f"error: {report['error']} (frames so far in {args.out})\n")
        return 1
    return 0


def run(args, config: SimulationOptions) -> int:
    return run_kind("particles", args, config)
