"""Terrain shaped by water, measured as geomorphologists measure land: after D8 routing
of a 513^2 diamond-square terrain before and after erosion (stream power, hydraulic), the
closed-pit share, channel concavity, Horton bifurcation ratio, Hack exponent and
hypsometric integral; the same figures for the real DEMs in
/work/shared/data/reference/dem (when present); and the speed of the erosion models.

Targets (eroded, stream power or hydraulic): pits <= 0.2 %, concavity 0.25-0.7, R_b 3-6,
Hack 0.45-0.65, HI 0.3-0.65; stream power on 1025^2 over 10^4 yr <= 60 s, hydraulic on
513^2 <= 30 s. Slopes for the concavity are taken over 5 cells (a DEM in whole metres
has steps a one-cell slope cannot see through); the real DEMs' network figures are
measured on them conditioned by Priority-Flood+epsilon, their pit share raw.
"""

import time
from pathlib import Path

import numpy as np

from procgen.terrain.erosion import ErosionConfig, hydraulic_erosion, stream_power
from procgen.terrain.heightfield import fractal_terrain
from procgen.terrain.metrics import terrain_figures

DEM_DIR = Path("/work/shared/data/reference/dem")
TARGETS = {"pit_share": (0.0, 0.002), "concavity": (0.25, 0.7),
           "bifurcation_ratio": (3.0, 6.0), "hack_exponent": (0.45, 0.65),
           "hypsometric_integral": (0.3, 0.65)}
REACH = 5


def _row(name, fig, check=False):
    d = fig.to_dict()
    cells = []
    for k, v in d.items():
        lo, hi = TARGETS[k]
        mark = ("" if not check else (" ok" if lo <= v <= hi else " MISS"))
        cells.append(f"{k} {v * 100:.3f} %{mark}" if k == "pit_share" else f"{k} {v:.3f}{mark}")
    print(f"   {name:<34}: " + ", ".join(cells), flush=True)
    return all(TARGETS[k][0] <= v <= TARGETS[k][1] for k, v in d.items())


def _read_dem(path):
    """Heights (NaN nodata) and the cell size (dx, dy) in metres."""
    import rasterio

    with rasterio.open(path) as src:
        z = src.read(1).astype(np.float64)
        if src.nodata is not None:
            z[z == src.nodata] = np.nan
        dx, dy = abs(src.res[0]), abs(src.res[1])
        if src.crs is not None and src.crs.is_geographic:  # degrees: metres at mid-latitude
            lat = np.radians(0.5 * (src.bounds.top + src.bounds.bottom))
            dx, dy = dx * 111_320.0 * np.cos(lat), dy * 110_574.0
        note = "no CRS: cells taken as metres" if src.crs is None else str(src.crs)
    return z, (dx, dy), note


def main():
    size, spacing = 513, 20.0
    z = fractal_terrain(size, rng=np.random.default_rng(0), height=150.0)
    print(f"   513^2 diamond-square, {spacing:g} m cells, height s.d. 150 m")
    _row("diamond-square (no erosion)", terrain_figures(z, spacing=spacing, reach=REACH))
    stream_power(fractal_terrain(65, rng=np.random.default_rng(0)), spacing=spacing)  # jit
    t = time.perf_counter()
    sp = stream_power(z, spacing=spacing, config=ErosionConfig())
    t_sp513 = time.perf_counter() - t
    ok_sp = _row("stream power, 10^4 yr", terrain_figures(sp, spacing=spacing, reach=REACH),
                 check=True)
    hydraulic_erosion(fractal_terrain(65, rng=np.random.default_rng(0)), spacing=spacing,
                      config=ErosionConfig(iterations=2))
    t, c = time.perf_counter(), time.process_time()
    hy = hydraulic_erosion(z, spacing=spacing, config=ErosionConfig())
    t_hy, c_hy = time.perf_counter() - t, time.process_time() - c
    try:
        ok_hy = _row("hydraulic (routed), 100 steps",
                     terrain_figures(hy, spacing=spacing, reach=REACH), check=True)
    except ValueError as exc:   # no channel network to measure
        ok_hy = False
        print(f"   hydraulic (routed), 100 steps   : no network to measure ({exc})")
    print(f"   eroded terrain within every target: stream power "
          f"{'PASS' if ok_sp else 'MISS'}, hydraulic {'PASS' if ok_hy else 'MISS'}")

    if DEM_DIR.is_dir():
        for path in sorted(p for p in DEM_DIR.iterdir() if p.suffix in (".tif", ".asc")):
            dem, sp_dem, note = _read_dem(path)
            fig = terrain_figures(dem, spacing=sp_dem, fill=True, reach=REACH)
            _row(f"real DEM {path.name}", fig)
            print(f"      {dem.shape[1]} x {dem.shape[0]} cells of {sp_dem[0]:.1f} x "
                  f"{sp_dem[1]:.1f} m, {np.nanmin(dem):.0f}-{np.nanmax(dem):.0f} m, {note}")
    else:
        print(f"   real DEMs: {DEM_DIR} not present, skipped")

    big = fractal_terrain(1025, rng=np.random.default_rng(0), height=150.0)
    t = time.perf_counter()
    stream_power(big, spacing=10.0, config=ErosionConfig(years=1e4))
    t_sp = time.perf_counter() - t
    print(f"   stream power 513^2 over 10^4 yr: {t_sp513:.1f} s")
    print(f"   stream power 1025^2 over 10^4 yr: {t_sp:.1f} s (target <= 60 s) "
          f"{'PASS' if t_sp <= 60 else 'MISS'}")
    print(f"   hydraulic 513^2, 100 steps: {t_hy:.1f} s, CPU {c_hy:.1f} s (target <= 30 s) "
          f"{'PASS' if t_hy <= 30 else 'MISS'}")


if __name__ == "__main__":
    main()
