"""``scanamp procgen terrain``: a fractal or tileable terrain mesh, eroded by water or
gravity if asked, coloured by ground material, with its water and a GeoTIFF DEM."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.config import Config, option
from procgen.terrain.erosion import KINDS, ErosionConfig
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
HELP = ("fractal terrain (diamond-square, fBm or ridged; tileable), eroded (stream power, "
        "hydraulic, thermal), coloured by material, with lakes and rivers or water at a level")

log = logging.getLogger(__name__)


def _water_path(out: Path) -> Path:
    return out.with_name(out.stem + ".water" + out.suffix)


def companions(args, config=None):
    out = args.out
    water = ([_water_path(out)]
             if config is not None and (config.water is not None or config.rivers) else [])
    dem = [args.dem] if getattr(args, "dem", None) is not None else []
    return water + dem + ([] if args.no_preview else [preview_path(out)])


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
    erosion: str = option("none", choices=KINDS, help="erosion model applied to the terrain")
    rates: ErosionConfig = option(default_factory=ErosionConfig,
                                  help="rates of the erosion models")
    rivers: bool = option(False, help="also write the lakes (filled to their spill points) "
                                      "and rivers (down the flow) as FILE.water.EXT")
    materials: bool = option(True, help="colour the ground by material (rock, scree, grass, "
                                        "forest floor, snow, water): PLY vertex colours")
    crs: str | None = option(None, help="coordinate system of the --dem GeoTIFF (EPSG:32632, "
                                        "WKT); a projected one in metres")


CONFIG = TerrainConfig


def add_arguments(p):
    add_output(p, kind="mesh")
    p.add_argument("--dem", type=Path, default=None,
                   help="also write the heightfield as a GeoTIFF DEM in metres (FILE.tif)")
    p.add_argument("--from-dem", type=Path, default=None,
                   help="start from this GeoTIFF DEM (projected, metres; --crs names the "
                        "CRS of one that has none) instead of a generated terrain; its "
                        "nodata cells take their nearest height")


def _crs_wkt(text: str, field: str) -> str:
    from rasterio.crs import CRS
    from rasterio.errors import CRSError

    try:
        crs = CRS.from_user_input(text)
    except CRSError as exc:
        raise ValueError(f"{field}: not a coordinate system ({exc})") from None
    if not crs.is_projected:
        raise ValueError(f"{field}: expected a projected CRS in metres, got "
                         f"{crs.to_string() or text!r} (its units are not metres)")
    return crs.to_wkt()


def _check(args, config: TerrainConfig):
    """Every input checked before anything is written: the start raster (or None) and
    the DEM's CRS as WKT."""
    from procgen.terrain import check_grid_size

    check_out(args.out, MESH_OUT)
    check_grid_size(config.size, "--size")
    if not 0 < config.extent < float("inf"):
        raise ValueError(f"--extent: expected a positive finite length, got {config.extent}")
    if config.water is not None and config.rivers:
        raise ValueError("--water: a level and --rivers (water down the flow) exclude "
                         "each other; give one")
    if args.dem is not None and args.dem.suffix.lower() not in (".tif", ".tiff"):
        raise ValueError(f"--dem: expected a file ending in .tif, got {str(args.dem)!r}")
    if config.crs is not None and args.dem is None and args.from_dem is None:
        raise ValueError("--crs: only a DEM has a coordinate system; give --dem or --from-dem")
    crs = None if config.crs is None else _crs_wkt(config.crs, "--crs")
    start = None
    if args.from_dem is not None:
        from core.io.raster import read_raster
        from core.validate import InputError

        start = read_raster(args.from_dem)
        if start.crs_wkt is None and crs is None:
            raise InputError("the DEM has no coordinate system, so its cell size may not "
                             "be metres; give --crs (e.g. EPSG:32632)", path=args.from_dem,
                             field="crs")
        if start.crs_wkt is not None:
            _crs_wkt(start.crs_wkt, f"{args.from_dem}: crs")
            crs = crs or start.crs_wkt
        if not np.isfinite(start.values).any() or min(start.values.shape) < 3:
            raise InputError("expected at least 3 x 3 cells with heights", path=args.from_dem,
                             field="values")
    return start, crs


def run(args, config: TerrainConfig) -> int:
    from core.io.mesh import write_mesh
    from core.io.raster import write_raster
    from procgen.terrain import fractal_terrain, tileable_terrain
    from procgen.terrain.erosion import erode
    from procgen.terrain.landscape import build_landscape, heightfield_raster

    out = args.out
    start, crs_wkt = _check(args, config)
    rng = np.random.default_rng(args.seed)
    if start is not None:
        z = _filled(start.values)
        step, origin = start.res, (start.x0, start.y0, 0.0)
    else:
        if config.tileable:
            z = tileable_terrain(config.size, rng=rng, hurst=config.hurst, height=config.height)
        else:
            z = fractal_terrain(config.size, rng=rng, method=config.method, hurst=config.hurst,
                                height=config.height)
        step = config.extent / (config.size - 1)
        origin = (-config.extent / 2, -config.extent / 2, 0.0)
    if config.erosion != "none":
        z = erode(z, spacing=step, kind=config.erosion, config=config.rates)
        log.info("eroded (%s): height range %.3g m", config.erosion, float(np.ptp(z)))
    water = "flow" if config.rivers else config.water
    land = build_landscape(z, spacing=step, origin=origin, water=water,
                           materials=config.materials, seed=args.seed)
    if land.shares:
        log.info("materials: %s", ", ".join(f"{k} {v:.1%}" for k, v in land.shares.items()))
    ground = land.ground
    if out.suffix.lower() == ".ply":  # PLY cannot hold per-corner UVs (OBJ keeps them)
        ground.triangle_uvs.clear()
    write_mesh(out, ground)
    log.info("wrote %s (%d vertices)", out, len(ground.vertices))
    meshes = [(ground, None if config.materials else (0.55, 0.5, 0.4))]
    if land.water is not None:
        if out.suffix.lower() == ".ply":
            land.water.triangle_uvs.clear()
        wpath = _water_path(out)
        write_mesh(wpath, land.water)
        log.info("wrote %s (%d triangles)", wpath, len(land.water.triangles))
        meshes.append((land.water, (0.2, 0.4, 0.8)))
    elif water is not None:
        log.warning("no water on this terrain (%s): no water mesh written",
                    "no lake or river" if config.rivers else f"nothing below {config.water:g}")
    if args.dem is not None:
        write_raster(args.dem, heightfield_raster(z, spacing=step, origin=origin[:2],
                                                  crs_wkt=crs_wkt))
        log.info("wrote %s (%d x %d, %g m cells)", args.dem, z.shape[1], z.shape[0], step)
    if not args.no_preview:
        log.info("wrote %s", render_preview(meshes, preview_path(out)))
    return 0


def _filled(values: np.ndarray) -> np.ndarray:
    """Nodata cells take the height of their nearest cell with one."""
    from scipy import ndimage

    bad = ~np.isfinite(values)
    if not bad.any():
        return values
    _, (ii, jj) = ndimage.distance_transform_edt(bad, return_indices=True)
    return values[ii, jj]
