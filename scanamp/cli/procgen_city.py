"""``scanamp procgen city --out city.ply``: roads grown after Parish and Mueller, lots along
them and a CSG building on each, heights following the population map."""

from __future__ import annotations

import logging

import numpy as np

from procgen.city import CityConfig
from scanamp.cli._procgen_common import (
    MESH_OUT,
    add_output,
    check_out,
    labelled_companions,
    preview_path,
    render_preview,
    write_parts,
)

NAME = "city"
GROUP = "procgen"
OUTPUT = "file"
HELP = ("a procedural city: highways and streets (Parish and Mueller), lots, CSG buildings "
        "by population; labelled mesh + preview")
CONFIG = CityConfig

log = logging.getLogger(__name__)

_COLORS = {"building": (0.78, 0.72, 0.62), "road": (0.25, 0.25, 0.27),
           "highway": (0.12, 0.12, 0.14), "ground": (0.62, 0.72, 0.5)}


def companions(args, config=None):
    return labelled_companions(args)


def add_arguments(p):
    add_output(p, kind="mesh")


def run(args, config: CityConfig) -> int:
    from core.meshes import make_mesh
    from procgen.city import generate_city

    out = check_out(args.out, MESH_OUT)
    city = generate_city(np.random.default_rng(args.seed), config)
    if len(city.triangles) == 0:
        raise RuntimeError("the city grew no roads: raise --max-segments or --size")
    v, f, part = city.vertices, city.triangles, city.part
    lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)   # the ground under the city
    lo, hi = lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)
    ground = make_mesh(np.array([[lo[0], lo[1], 0.0], [hi[0], lo[1], 0.0], [hi[0], hi[1], 0.0],
                                 [lo[0], hi[1], 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    kinds = {0: "building", 1: "road", 2: "highway"}
    pieces = []
    for k, kind in kinds.items():
        tri = f[np.all(part[f] == k, axis=1)]
        if len(tri):
            pieces.append((kind, make_mesh(v, tri)))
    pieces.append(("ground", ground))
    write_parts(out, [(m, kind, _COLORS[kind]) for kind, m in pieces],
                label_of={"building": "building", "road": "road", "highway": "road",
                          "ground": "ground"})
    log.info("wrote %s: %d road segments (%d highway), %d buildings", out, len(city.edges),
             int(city.highway.sum()), len(city.footprints))
    if not args.no_preview:
        log.info("wrote %s", render_preview([(m, _COLORS[k]) for k, m in pieces],
                                            preview_path(out)))
    return 0
