"""``scanamp procgen terrain``: a fractal or tileable terrain mesh, optional water."""

from __future__ import annotations

import logging

import numpy as np

from scanamp.commands._procgen_common import (
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
    return [] if args.no_preview else [preview_path(args.out)]


def add_arguments(p):
    p.add_argument("--size", type=int, default=257, help="samples a side, 2**n + 1 (257)")
    p.add_argument("--method", default="diamond_square",
                   choices=["diamond_square", "fbm", "ridged"], help="generator")
    p.add_argument("--tileable", action="store_true",
                   help="a tile that repeats seamlessly (periodic fBm; ignores --method)")
    p.add_argument("--hurst", type=float, default=0.8, help="Hurst exponent in (0, 1)")
    p.add_argument("--extent", type=float, default=10.0, help="side of the square in metres")
    p.add_argument("--height", type=float, default=0.6, help="height standard deviation (m)")
    p.add_argument("--water", type=float, default=None, metavar="LEVEL",
                   help="also write a water mesh at this elevation (m) as FILE.water.EXT")
    add_output(p, kind="mesh")


def run(args) -> int:
    from core.mesh_io import write_mesh
    from procgen.terrain import (
        check_grid_size,
        fractal_terrain,
        heightfield_to_mesh,
        tileable_terrain,
        water_mesh,
    )

    out = check_out(args.out, MESH_OUT)
    check_grid_size(args.size, "--size")
    if not 0 < args.extent < float("inf"):
        raise ValueError(f"--extent: expected a positive finite length, got {args.extent}")
    rng = np.random.default_rng(args.seed)
    if args.tileable:
        z = tileable_terrain(args.size, rng=rng, hurst=args.hurst, height=args.height)
    else:
        z = fractal_terrain(args.size, rng=rng, method=args.method, hurst=args.hurst,
                            height=args.height)
    step = args.extent / (args.size - 1)
    origin = (-args.extent / 2, -args.extent / 2, 0.0)
    ground = heightfield_to_mesh(z, spacing=step, origin=origin)
    if out.suffix.lower() == ".ply":  # PLY cannot hold per-corner UVs (OBJ keeps them)
        ground.triangle_uvs.clear()
    write_mesh(out, ground)
    log.info("wrote %s (%d vertices)", out, len(ground.vertices))
    meshes = [(ground, (0.55, 0.5, 0.4))]
    if args.water is not None:
        water = water_mesh(z, args.water, spacing=step, origin=origin)
        if out.suffix.lower() == ".ply":
            water.triangle_uvs.clear()
        wpath = out.with_name(out.stem + ".water" + out.suffix)
        if len(water.triangles):
            write_mesh(wpath, water)
            log.info("wrote %s (%d triangles)", wpath, len(water.triangles))
            meshes.append((water, (0.2, 0.4, 0.8)))
        else:
            log.warning("no terrain below the water level %g: no water mesh written", args.water)
    if not args.no_preview:
        log.info("wrote %s", render_preview(meshes, preview_path(out)))
    return 0
