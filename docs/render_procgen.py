"""Render the city and a gallery of 12 plants from the shape grammar (docs/lsystem.md),
coloured by part, with pyvista off-screen (EGL).

Usage: ``python docs/render_procgen.py OUT_DIR`` (writes ``city.png`` and
``plant_gallery.png``; the copies under ``docs/img`` come from here).
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import pyvista as pv  # noqa: E402

pv.OFF_SCREEN = True


def _colored(v, f, rgb):
    from core.meshes import make_mesh, to_pyvista

    mesh = to_pyvista(make_mesh(v, f, compute_normals=False))
    mesh.point_data["rgb"] = (np.asarray(rgb) * 255).astype(np.uint8)
    return mesh


def city(out: Path, seed: int = 0) -> Path:
    from procgen.city import ELEMENTS, CityConfig, generate_city
    from scanamp.commands.procgen_city import COLORS

    c = generate_city(np.random.default_rng(seed), CityConfig(size=1000, max_segments=250))
    rgb = np.array([COLORS[k] for k in ELEMENTS])[c.element]
    v = c.vertices[c.triangles].reshape(-1, 3)       # a colour per triangle
    f = np.arange(len(v)).reshape(-1, 3)
    pl = pv.Plotter(off_screen=True, window_size=(960, 720))
    pl.add_mesh(_colored(v, f, np.repeat(rgb, 3, axis=0)), scalars="rgb", rgb=True)
    lo, hi = c.vertices[:, :2].min(0), c.vertices[:, :2].max(0)
    ground = pv.Plane(center=(*(lo + hi) / 2, 0.0), i_size=hi[0] - lo[0], j_size=hi[1] - lo[1])
    pl.add_mesh(ground, color=COLORS["ground"])
    pl.set_background("white")
    pl.view_isometric()
    pl.camera.elevation = 10
    pl.camera.zoom(1.6)
    path = out / "city.png"
    pl.screenshot(str(path))
    pl.close()
    return path


def plant_gallery(out: Path, seeds=range(12)) -> Path:
    from procgen.shape_grammar import plant_mesh
    from scanamp.commands.procgen_plant import BARK, LEAF

    pl = pv.Plotter(off_screen=True, shape=(3, 4), window_size=(1200, 900), border=False)
    for k, seed in enumerate(seeds):
        v, f, leaf = plant_mesh(np.random.default_rng(seed), leaves=True)
        pl.subplot(k // 4, k % 4)
        pl.add_mesh(_colored(v, f, np.where(leaf[:, None], LEAF, BARK)), scalars="rgb",
                    rgb=True, smooth_shading=True)
        pl.add_text(f"seed {seed}", font_size=9, color="black")
        pl.set_background("white")
        pl.view_xz()
        pl.reset_camera()
        pl.camera.zoom(0.95)
    path = out / "plant_gallery.png"
    pl.screenshot(str(path))
    pl.close()
    return path


def main(argv):
    out = Path(argv[0]) if argv else Path("docs/img")
    out.mkdir(parents=True, exist_ok=True)
    sys.stdout.write(f"{city(out)}\n{plant_gallery(out)}\n")


if __name__ == "__main__":
    main(sys.argv[1:])
