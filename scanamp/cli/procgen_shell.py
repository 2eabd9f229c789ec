"""``scanamp procgen shell --out shell.ply --shape turbinate``: a seashell from Cortie's
parameterisation (the five shape classes of Fowler et al.), or the helico-spiral model."""

from __future__ import annotations

import logging
from dataclasses import dataclass

from core.config import Config, option
from procgen.shells import SHAPES
from scanamp.cli._procgen_common import (
    MESH_OUT,
    add_output,
    check_out,
    labelled_companions,
    preview_path,
    render_preview,
    write_parts,
)

NAME = "shell"
GROUP = "procgen"
OUTPUT = "file"
HELP = "a seashell (Cortie's model: turbinate, patelliform, tubular, spherical, discoid; " \
       "or the helico-spiral)"

log = logging.getLogger(__name__)

COLOR = (0.86, 0.76, 0.62)


@dataclass
class ShellConfig(Config):
    """Options of ``scanamp procgen shell``."""

    shape: str = option("turbinate", choices=(*SHAPES, "helicospiral"),
                        help="a Cortie shape class, or the helico-spiral model")
    size: float = option(0.1, unit="m", range="(0, inf)", help="largest extent of the shell")
    n_theta: int = option(400, range="[8, 20000]", help="samples along the coiling")
    n_s: int = option(48, range="[3, 2000]", help="samples around the aperture")


CONFIG = ShellConfig


def companions(args, config=None):
    return labelled_companions(args)


def add_arguments(p):
    add_output(p, kind="mesh")


def run(args, config: ShellConfig) -> int:
    import numpy as np

    from core.meshes import make_mesh
    from procgen.shells import cortie_shell, helicospiral_shell

    out = check_out(args.out, MESH_OUT)
    if config.shape == "helicospiral":
        v, f = helicospiral_shell(n_path=config.n_theta, n_profile=config.n_s)
    else:
        v, f = cortie_shell(config.shape, n_theta=config.n_theta, n_s=config.n_s)
    v = v - v.min(axis=0)
    v = v * (config.size / float(np.max(v.max(axis=0))))
    mesh = make_mesh(v, f)
    write_parts(out, [(mesh, "shell", COLOR)], label_of={"shell": "shell"})
    log.info("wrote %s (%d triangles)", out, len(f))
    if not args.no_preview:
        log.info("wrote %s", render_preview([(mesh, COLOR)], preview_path(out)))
    return 0
