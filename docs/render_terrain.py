"""Render a terrain before and after erosion (stream power, hydraulic), coloured by ground
material with solid textures, with its water: a level sheet before, lakes and rivers that
follow the flow after (docs/terrain.md). pyvista off-screen (EGL), a sun light, a sky.

Usage: ``python docs/render_terrain.py OUT_DIR`` (writes ``terrain_before.png``,
``terrain_stream_power.png``, ``terrain_hydraulic.png`` and ``terrain_maps.png``; the
copies under ``docs/img`` come from here).
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import pyvista as pv  # noqa: E402

pv.OFF_SCREEN = True
SIZE, EXTENT, HEIGHT = 257, 8000.0, 90.0


def _render(land, path: Path, title: str) -> Path:
    from core.meshes import to_pyvista

    pl = pv.Plotter(off_screen=True, window_size=(1100, 700), lighting="none")
    pl.add_mesh(to_pyvista(land.ground), scalars="rgb", rgb=True, smooth_shading=True,
                ambient=0.25, diffuse=0.85, specular=0.0)
    if land.water is not None:
        pl.add_mesh(to_pyvista(land.water), color=(0.16, 0.34, 0.55), smooth_shading=True,
                    ambient=0.3, specular=0.6, specular_power=40)
    pl.add_light(pv.Light(position=(-1.0, -0.6, 0.55), light_type="scene light",
                          positional=False, intensity=1.0))
    pl.set_background((0.55, 0.70, 0.90), top=(0.20, 0.40, 0.75))
    pl.camera_position = [(-0.85 * EXTENT, -1.05 * EXTENT, 0.55 * EXTENT), (0, 0, 0),
                          (0, 0, 1)]
    pl.camera.view_angle = 32
    pl.add_text(title, font_size=11, color="white")
    pl.screenshot(str(path))
    pl.close()
    return path


def main(out: Path):
    from procgen.terrain.erosion import ErosionConfig, hydraulic_erosion, stream_power
    from procgen.terrain.heightfield import fractal_terrain
    from procgen.terrain.landscape import build_landscape
    from procgen.terrain.metrics import pit_share

    out.mkdir(parents=True, exist_ok=True)
    step = EXTENT / (SIZE - 1)
    origin = (-EXTENT / 2, -EXTENT / 2, 0.0)
    z = fractal_terrain(SIZE, rng=np.random.default_rng(4), height=HEIGHT)
    sp = stream_power(z, spacing=step, config=ErosionConfig())
    hy = hydraulic_erosion(z, spacing=step, config=ErosionConfig())
    level = float(np.quantile(z, 0.12))
    shots = [("terrain_before.png", z, level, "diamond-square, water at a level"),
             ("terrain_stream_power.png", sp, "flow",
              "stream power, 10^4 yr: lakes to their spill points, rivers down the flow"),
             ("terrain_hydraulic.png", hy, "flow",
              "hydraulic erosion, 100 steps of water routed down the land")]
    for name, h, water, title in shots:
        land = build_landscape(h, spacing=step, origin=origin, water=water, seed=1)
        shares = ", ".join(f"{k} {v:.0%}" for k, v in land.shares.items())
        sys.stdout.write(f"{name}: pits {pit_share(h):.2%}; {shares}\n")
        _render(land, out / name, title)
    _maps(z, sp, step, out / "terrain_maps.png")


def _maps(z, sp, step, path):
    """Hillshade and drainage area, before and after stream power."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import LightSource
    from matplotlib.figure import Figure

    from procgen.terrain.flow import route_flow

    fig = Figure(figsize=(12, 6.4), dpi=90)
    FigureCanvasAgg(fig)
    ls = LightSource(315, 40)
    for col, (h, name) in enumerate([(z, "diamond-square"), (sp, "stream power")]):
        ax = fig.add_subplot(2, 2, 1 + col)
        ax.imshow(ls.hillshade(h, dx=step, dy=step), cmap="gray", origin="lower")
        ax.set_title(f"{name}: hillshade")
        ax.set_axis_off()
        ax = fig.add_subplot(2, 2, 3 + col)
        ax.imshow(np.log10(route_flow(h, spacing=step).area), cmap="Blues", origin="lower")
        ax.set_title(f"{name}: log10 drainage area (D8, no filling)")
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(path)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "docs/img"))
