"""``scanamp procgen city --out city.ply``: roads grown after Parish and Mueller by street
pattern, lots with street frontage, buildings from a split grammar (rule files are data),
with the roads, lots and buildings as GeoJSON and the buildings as CityJSON LoD2."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from core.validate import InputError
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
HELP = ("a procedural city: roads by pattern (Parish and Mueller), lots, buildings from a "
        "split grammar; labelled mesh, GeoJSON roads/lots/buildings, CityJSON, preview")
CONFIG = CityConfig

log = logging.getLogger(__name__)

COLORS = {"wall": (0.82, 0.76, 0.66), "window": (0.35, 0.45, 0.55),
          "door": (0.40, 0.25, 0.15), "ledge": (0.92, 0.90, 0.86),
          "roof": (0.62, 0.28, 0.22), "street": (0.25, 0.25, 0.27),
          "highway": (0.12, 0.12, 0.14), "ground": (0.62, 0.72, 0.5),
          "tree_bark": (0.36, 0.27, 0.2), "tree_leaf": (0.25, 0.5, 0.18)}
_LABEL_OF = {"wall": "building", "window": "window", "door": "building", "ledge": "building",
             "roof": "roof", "street": "road", "highway": "road", "ground": "ground",
             "tree_bark": "bark", "tree_leaf": "leaf"}


def companions(args, config=None):
    from procgen.city import city_paths

    return labelled_companions(args) + city_paths(args.out)


def add_arguments(p):
    add_output(p, kind="mesh")
    for name, what in (("population", "population density (any positive scale)"),
                       ("water", "water (non-zero cells)"),
                       ("elevation", "ground elevation in metres")):
        p.add_argument(f"--{name}", type=Path, default=None, metavar="FILE",
                       help=f"map of {what} over the square city, north up: a GeoTIFF, a "
                            f"grey PNG or a 2-D .npy; all maps given share one square shape")


def read_map(path: Path, field: str) -> np.ndarray:
    """A 2-D map from a GeoTIFF, an image or a ``.npy`` file, row 0 to the north."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path, field=field)
    suffix = path.suffix.lower()
    if suffix in (".tif", ".tiff"):
        from core.io.raster import read_raster

        return read_raster(path).values[::-1].copy()
    if suffix == ".npy":
        try:
            grid = np.load(path, allow_pickle=False)
        except Exception as e:
            raise InputError(f"not a readable .npy array ({e})", path=path, field=field) \
                from None
        if grid.dtype.kind not in "biuf":
            raise InputError(f"expected numbers, got dtype {grid.dtype}", path=path,
                             field=field)
        return np.asarray(grid, np.float64)
    from core.io.image import read_image

    return read_image(path, grayscale=True).astype(np.float64)


def run(args, config: CityConfig) -> int:
    from core.meshes import make_mesh
    from procgen.city import ELEMENTS, city_maps, generate_city, street_statistics
    from procgen.city.io import write_city_files

    out = check_out(args.out, MESH_OUT)
    given = {k: getattr(args, k, None) for k in ("population", "water", "elevation")}
    rasters = {k: read_map(v, k) for k, v in given.items() if v is not None}
    rng = np.random.default_rng(args.seed)
    maps = city_maps(config, rng, paths={k: str(v) for k, v in given.items() if v}, **rasters)
    city = generate_city(rng, config, maps=maps)
    if len(city.triangles) == 0:
        raise RuntimeError("the city grew no roads: raise --max-segments or --size")
    v, f = city.vertices, city.triangles
    lo, hi = v[:, :2].min(axis=0), v[:, :2].max(axis=0)   # the ground under the city
    lo, hi = lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)
    ground = make_mesh(np.array([[lo[0], lo[1], 0.0], [hi[0], lo[1], 0.0], [hi[0], hi[1], 0.0],
                                 [lo[0], hi[1], 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    pieces = []
    for code, kind in enumerate(ELEMENTS):
        tri = f[city.element == code]
        if len(tri) and kind in COLORS:
            pieces.append((kind, make_mesh(v, tri)))
    pieces.append(("ground", ground))
    if city.trees is not None and city.trees.stand is not None:   # --tree-species
        from procgen.weber_penn.appearance import LEAF_LABEL

        trees = city.trees.stand.mesh()
        leaf = trees.labels[trees.triangles[:, 0]] == LEAF_LABEL
        pieces += [("tree_bark", make_mesh(trees.vertices, trees.triangles[~leaf])),
                   ("tree_leaf", make_mesh(trees.vertices, trees.triangles[leaf]))]
    write_parts(out, [(m, kind, COLORS[kind]) for kind, m in pieces], label_of=_LABEL_OF)
    write_city_files(city, out)
    stats = street_statistics(city.nodes, city.edges)
    log.info("wrote %s: %d road segments (%d highway), %d lots, %d buildings, %d trees; "
             "streets: orientation order %.2f, mean degree %.2f, dead ends %.0f %%, "
             "circuity %.3f", out, len(city.edges), int(city.highway.sum()), len(city.lots),
             len(city.buildings), 0 if city.trees is None else len(city.trees.positions),
             stats["orientation_order"], stats["mean_degree"],
             100 * stats["dead_end_share"], stats["circuity"])
    if not args.no_preview:
        log.info("wrote %s", render_preview([(m, COLORS[k]) for k, m in pieces],
                                            preview_path(out)))
    return 0
