"""``scanamp procgen hypertexture``: Perlin-Hoffert hypertexture of a shape or a mesh."""

from __future__ import annotations

import logging

from scanamp.commands._procgen_common import (
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


def add_arguments(p):
    p.add_argument("shape", choices=["sphere", "egg", "sweep", "mesh"], help="base shape")
    p.add_argument("--mesh", default=None, help="closed input mesh (shape 'mesh')")
    p.add_argument("--polyline", default="0,0,0;1,0,0;1,1,0.5",
                   help="sweep path 'x,y,z;x,y,z;...' in metres (shape 'sweep')")
    p.add_argument("--radius", type=float, default=1.0, help="sphere/egg/sweep radius (m)")
    p.add_argument("--noise", choices=["turbulence", "fbm"], default="turbulence")
    p.add_argument("--amplitude", type=float, default=0.1, help="noise amplitude (m)")
    p.add_argument("--frequency", type=float, default=4.0, help="noise frequency (1/m)")
    p.add_argument("--octaves", type=int, default=5)
    p.add_argument("--bias", type=float, default=0.5, help="Perlin bias in (0, 1)")
    p.add_argument("--gain", type=float, default=0.5, help="Perlin gain in (0, 1)")
    p.add_argument("--resolution", type=int, default=96, help="voxels along the longest side")
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


def run(args) -> int:
    from core.mesh_io import read_mesh, write_mesh
    from procgen.implicit import egg_sdf, hypertexture, sphere_sdf, sweep_sdf

    out = check_out(args.out, MESH_OUT)
    if args.shape == "mesh":
        if not args.mesh:
            raise ValueError("--mesh: required for shape 'mesh'")
        shape = read_mesh(args.mesh)
        if len(shape.triangles) == 0:
            raise ValueError(f"--mesh: {args.mesh}: the mesh has no triangles")
    elif args.shape == "sphere":
        shape = sphere_sdf(radius=args.radius)
    elif args.shape == "egg":
        shape = egg_sdf(args.radius)
    else:
        shape = sweep_sdf(_polyline(args.polyline), args.radius)
    mesh = hypertexture(shape, noise=args.noise, amplitude=args.amplitude,
                        frequency=args.frequency, octaves=args.octaves, bias=args.bias,
                        gain=args.gain, resolution=args.resolution, seed=args.seed)
    write_mesh(out, mesh)
    log.info("wrote %s (%d vertices, %d triangles)", out, len(mesh.vertices),
             len(mesh.triangles))
    if not args.no_preview:
        log.info("wrote %s", render_preview([(mesh, (0.8, 0.7, 0.55))], preview_path(out)))
    return 0
