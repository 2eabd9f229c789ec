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
    variants: int = option(1, range="[1, 1000]",
                           help="amplified results from seeds seed, seed+1, ...: DIR/seed_N/ "
                                "each, and DIR/contact_sheet.png")
    turntable: int = option(0, range="[0, 3600]",
                            help="frames of a turntable animation of each result "
                                 "(turntable.mp4; 0: none)")
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
    from scanamp.amplify import run_variants

    if config.variants > 1:
        first = 0 if config.seed is None else config.seed
        out = run_variants(args.mesh, args.recipe, args.out,
                           seeds=range(first, first + config.variants), up=config.up,
                           turntable=config.turntable)
    else:
        out = amplify_run(args.mesh, args.recipe, args.out, seed=config.seed, up=config.up,
                          turntable=config.turntable)
        _warn_if_close(out)
    log.info("wrote %s", out)
    return 0


def _warn_if_close(out) -> None:
    """A warning naming --up when up came from the mesh and the runner-up was close."""
    import json
    from pathlib import Path

    from reconstruct.surface.up import is_close

    report = Path(out) / "report.json"
    up = json.loads(report.read_text()).get("up", {}) if report.is_file() else {}
    if is_close(up):
        d = up["decision"]
        alt = ",".join(f"{x:.3f}" for x in d["runner_up"]["up"])
        log.warning("up %s was a close call (decided by %s; the runner-up %s, %.0f degrees "
                    "away, scored within %.0f %%): if the result stands on a wall, pass "
                    "--up %s", ",".join(f"{x:.3f}" for x in up["up"]), d["cue"], alt,
                    d["runner_up"]["angle_deg"], 100 * d["margin"], alt)
