"""``scanamp procgen hypertexture``: Perlin-Hoffert hypertexture of a shape or a mesh."""

from __future__ import annotations

import logging
from dataclasses import dataclass

from core.config import Config, option
from scanamp.cli._procgen_common import (
    MESH_OUT,
    add_output,
    check_out,
    preview_path,
    render_preview,
)

NAME = "hypertexture"
GROUP = "procgen"
OUTPUT = "file"
HELP = "hypertexture a sphere, the fractal egg, a swept polyline or a mesh (marching cubes)"

log = logging.getLogger(__name__)


def companions(args, config=None):
    return [] if args.no_preview else [preview_path(args.out)]


@dataclass
class HypertextureConfig(Config):
    """Options of ``scanamp procgen hypertexture``."""

    mesh: str | None = option(None, help="closed input mesh (shape 'mesh')")
    polyline: str = option("0,0,0;1,0,0;1,1,0.5",
                           help="sweep path 'x,y,z;x,y,z;...' in metres (shape 'sweep')")
    radius: float = option(1.0, unit="m", range="(0, inf)", help="sphere/egg/sweep radius")
    noise: str = option("turbulence", choices=("turbulence", "fbm"), help="noise of the "
                                                                          "density")
    amplitude: float = option(0.1, unit="m", range="[0, inf)", help="noise amplitude")
    frequency: float = option(4.0, unit="1/m", range="(0, inf)", help="noise frequency")
    octaves: int = option(5, range="[1, 16]", help="noise octaves")
    bias: float = option(0.5, range="(0, 1)", help="Perlin bias")
    gain: float = option(0.5, range="(0, 1)", help="Perlin gain")
    resolution: int = option(96, range="[8, 1024]", help="voxels along the longest side")


CONFIG = HypertextureConfig


def add_arguments(p):
    p.add_argument("shape", choices=["sphere", "egg", "sweep", "mesh"], help="base shape")
    add_output(p, kind="mesh")


def _polyline(text: str):
    import numpy as np

    try:
        pts = np.array([[float(c) for c in part.split(",")] for part in text.split(";")
                        if part.strip()])
    except ValueError:
        raise ValueError(f"--polyline: expected 'x,y,z;x,y,z;...', got {text!r}") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2:
        raise ValueError(f"--polyline: expected at least two x,y,z points, got {text!r}")
    return pts


def run(args, config: HypertextureConfig) -> int:
    from core.io.mesh import read_mesh, write_mesh
    from procgen.implicit import egg_sdf, hypertexture, sphere_sdf, sweep_sdf

    out = check_out(args.out, MESH_OUT)
    c = config
    if args.shape == "mesh":
        if not c.mesh:
            raise ValueError("--mesh: required for shape 'mesh'")
        shape = read_mesh(c.mesh)
        if len(shape.triangles) == 0:
            raise ValueError(f"--mesh: {c.mesh}: the mesh has no triangles")
    elif args.shape == "sphere":
        shape = sphere_sdf(radius=c.radius)
    elif args.shape == "egg":
        shape = egg_sdf(c.radius)
    else:
        shape = sweep_sdf(_polyline(c.polyline), c.radius)
    mesh = hypertexture(shape, noise=c.noise, amplitude=c.amplitude, frequency=c.frequency,
                        octaves=c.octaves, bias=c.bias, gain=c.gain,
                        resolution=c.resolution, seed=args.seed)
    write_mesh(out, mesh)
    log.info("wrote %s (%d vertices, %d triangles)", out, len(mesh.vertices),
             len(mesh.triangles))
    if not args.no_preview:
        log.info("wrote %s", render_preview([(mesh, (0.8, 0.7, 0.55))], preview_path(out)))
    return 0
