"""``scanamp procgen terrain``: a fractal or tileable terrain mesh, optional water."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from scanamp.cli._procgen_common import (
    MESH_OUT,
    add_output,
    check_out,
    preview_path,
    render_preview,
)

NAME = "terrain"
GROUP = "procgen"
OUTPUT = "file"
HELP = "fractal terrain (diamond-square, fBm or ridged; tileable) as a mesh, with water"

log = logging.getLogger(__name__)


def companions(args, config=None):
    out = args.out
    water = ([out.with_name(out.stem + ".water" + out.suffix)]
             if config is not None and config.water is not None else [])
    return water + ([] if args.no_preview else [preview_path(out)])


@dataclass
class TerrainConfig(Config):
    """Options of ``scanamp procgen terrain``."""

    size: int = option(257, range="[3, 8193]", help="samples a side, 2**n + 1")
    method: str = option("diamond_square", choices=("diamond_square", "fbm", "ridged"),
                         help="generator")
    tileable: bool = option(False, help="a tile that repeats seamlessly (periodic fBm; "
                                        "ignores --method)")
    hurst: float = option(0.8, range="(0, 1)", help="Hurst exponent")
    extent: float = option(10.0, unit="m", range="(0, inf)", help="side of the square")
    height: float = option(0.6, unit="m", range="[0, inf)", help="height standard deviation")
    water: float | None = option(None, unit="m", help="also write a water mesh at this "
                                                      "elevation as FILE.water.EXT")


CONFIG = TerrainConfig


def add_arguments(p):
    add_output(p, kind="mesh")


def run(args, config: TerrainConfig) -> int:
    from core.io.mesh import write_mesh
    from procgen.terrain import (
        check_grid_size,
        fractal_terrain,
        heightfield_to_mesh,
        tileable_terrain,
        water_mesh,
    )

    out = check_out(args.out, MESH_OUT)
    check_grid_size(config.size, "--size")
    if not 0 < config.extent < float("inf"):
        raise ValueError(f"--extent: expected a positive finite length, got {config.extent}")
    rng = np.random.default_rng(args.seed)
    if config.tileable:
        z = tileable_terrain(config.size, rng=rng, hurst=config.hurst, height=config.height)
    else:
        z = fractal_terrain(config.size, rng=rng, method=config.method, hurst=config.hurst,
                            height=config.height)
    step = config.extent / (config.size - 1)
    origin = (-config.extent / 2, -config.extent / 2, 0.0)
    ground = heightfield_to_mesh(z, spacing=step, origin=origin)
    if out.suffix.lower() == ".ply":  # PLY cannot hold per-corner UVs (OBJ keeps them)
        ground.triangle_uvs.clear()
    write_mesh(out, ground)
    log.info("wrote %s (%d vertices)", out, len(ground.vertices))
    meshes = [(ground, (0.55, 0.5, 0.4))]
    if config.water is not None:
        water = water_mesh(z, config.water, spacing=step, origin=origin)
        if out.suffix.lower() == ".ply":
            water.triangle_uvs.clear()
        wpath = out.with_name(out.stem + ".water" + out.suffix)
        if len(water.triangles):
            write_mesh(wpath, water)
            log.info("wrote %s (%d triangles)", wpath, len(water.triangles))
            meshes.append((water, (0.2, 0.4, 0.8)))
        else:
            log.warning("no terrain below the water level %g: no water mesh written", config.water)
    if not args.no_preview:
        log.info("wrote %s", render_preview(meshes, preview_path(out)))
    return 0
