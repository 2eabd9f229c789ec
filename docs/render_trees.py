"""Render the Weber & Penn species gallery, the seasons and the bark swatches of
docs/trees.md with pyvista off-screen (EGL).

Usage: ``python docs/render_trees.py [OUT_DIR]`` (default ``docs/img``).
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import pyvista as pv  # noqa: E402

from procgen.weber_penn import (  # noqa: E402
    bark_texture,
    grow,
    load_species,
    species_names,
    tree_mesh,
)
from scanamp.cli.procgen_tree import add_tree  # noqa: E402

pv.OFF_SCREEN = True


def gallery(out: Path):
    names = species_names()
    cols = 5
    rows = (len(names) + cols - 1) // cols
    pl = pv.Plotter(off_screen=True, shape=(rows, cols), window_size=(300 * cols, 380 * rows))
    for i, name in enumerate(names):
        p = load_species(name)
        t = grow(p, height=p["Scale"], rng=np.random.default_rng(1))
        pl.subplot(i // cols, i % cols)
        add_tree(pl, tree_mesh(t, rng=np.random.default_rng(2)),
             f"{p.species['common']}, {t.height:.0f} m")
    pl.screenshot(str(out / "trees_gallery.png"))
    pl.close()


def thumbnails(out: Path):
    """One small render a species (docs/trees.md puts each beside the species' name)."""
    (out / "trees").mkdir(exist_ok=True)
    for name in species_names():
        p = load_species(name)
        t = grow(p, height=p["Scale"], rng=np.random.default_rng(1))
        pl = pv.Plotter(off_screen=True, window_size=(220, 280))
        add_tree(pl, tree_mesh(t, rng=np.random.default_rng(2)), "")
        pl.screenshot(str(out / "trees" / f"{name}.png"))
        pl.close()


def seasons(out: Path):
    cases = [("european_beech", "summer", "full"), ("european_beech", "autumn", "full"),
             ("european_beech", "winter", "full"), ("european_beech", "summer", "cards"),
             ("european_larch", "autumn", "full")]
    pl = pv.Plotter(off_screen=True, shape=(1, len(cases)), window_size=(300 * len(cases), 380))
    for i, (name, season, lod) in enumerate(cases):
        t = grow(load_species(name), height=18.0, rng=np.random.default_rng(3))
        pl.subplot(0, i)
        add_tree(pl, tree_mesh(t, rng=np.random.default_rng(4), season=season, lod=lod),
             f"{name.replace('_', ' ')}: {season}{', leaf cards' if lod == 'cards' else ''}")
    pl.screenshot(str(out / "trees_seasons.png"))
    pl.close()


def barks(out: Path):
    from core.io.image import write_image

    names = species_names()
    tiles = [bark_texture(load_species(n), size=(128, 128), extent=0.4) for n in names]
    row = np.concatenate([np.pad(t, ((4, 4), (4, 4), (0, 0)), constant_values=1.0)
                          for t in tiles], 1)
    write_image(out / "trees_bark.png", np.round(row * 255).astype(np.uint8))


def ivy_facade(out: Path):
    """Ivy (the vines recipe's climbing plant) on a facade, and street trees of the city."""
    from core.meshes import make_mesh, mesh_arrays
    from data_synth.facades import facade_mesh
    from procgen.amplify.vines import grow_vines

    v, f, _ = facade_mesh(np.random.default_rng(1), width=12.0, height=9.0, floors=3, bays=4,
                          rotate=False)
    res = grow_vines(make_mesh(v, f), rng=np.random.default_rng(4), count=10, length=9.0,
                     step=0.06, radius=0.015, wander_deg=20.0, slope_min_deg=60.0, climb=0.5,
                     taper=0.7, branches=1.0, leaf_size=0.12, leaf_spacing=0.1)
    pv_faces = lambda t: np.hstack([np.full((len(t), 1), 3), t]).ravel()  # noqa: E731
    pl = pv.Plotter(off_screen=True, window_size=(900, 640))
    pl.add_mesh(pv.PolyData(v, pv_faces(f)), color=(0.80, 0.74, 0.64))
    vv, ff = mesh_arrays(res.mesh)
    leaf = res.leaf[ff].all(1)
    pl.add_mesh(pv.PolyData(vv, pv_faces(ff[~leaf])), color=(0.36, 0.27, 0.2))
    pl.add_mesh(pv.PolyData(vv, pv_faces(ff[leaf])), color=(0.18, 0.42, 0.14))
    pl.camera_position = [(6.0, -16.0, 6.5), (6.0, 0.0, 4.5), (0.0, 0.0, 1.0)]
    pl.screenshot(str(out / "ivy_facade.png"))
    pl.close()


def city_trees(out: Path):
    """A small city whose streets are lined with Weber & Penn trees (procgen.city.trees)."""
    from procgen.city import CityConfig, generate_city
    from procgen.weber_penn.appearance import LEAF_LABEL

    cfg = CityConfig(size=300.0, max_segments=10, parks=1, park_radius=40.0, river_width=0.0,
                     max_floors=6, tree_species="lombardy_poplar,sycamore_maple",
                     tree_spacing=14.0, park_trees=50.0)
    city = generate_city(np.random.default_rng(4), cfg)
    faces = lambda t: np.hstack([np.full((len(t), 1), 3), t]).ravel()  # noqa: E731
    pl = pv.Plotter(off_screen=True, window_size=(1000, 640))
    pl.add_mesh(pv.PolyData(city.vertices, faces(city.triangles)), color=(0.80, 0.76, 0.70))
    lo, hi = city.vertices[:, :2].min(0), city.vertices[:, :2].max(0)
    pl.add_mesh(pv.Plane(center=(*(lo + hi) / 2, -0.05), i_size=hi[0] - lo[0] + 20,
                         j_size=hi[1] - lo[1] + 20), color=(0.55, 0.62, 0.45))
    m = city.trees.stand.mesh()
    leaf = m.labels[m.triangles[:, 0]] == LEAF_LABEL
    for sel in (~leaf, leaf):
        poly = pv.PolyData(m.vertices, faces(m.triangles[sel]))
        poly.point_data["rgb"] = (m.colors * 255).astype(np.uint8)
        pl.add_mesh(poly, scalars="rgb", rgb=True)
    c = (lo + hi) / 2
    pl.camera_position = [(c[0] - 120, c[1] - 170, 110), (c[0], c[1], 0.0), (0, 0, 1)]
    pl.screenshot(str(out / "city_trees.png"))
    pl.close()


if __name__ == "__main__":
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "img"
    out.mkdir(parents=True, exist_ok=True)
    gallery(out)
    thumbnails(out)
    seasons(out)
    barks(out)
    ivy_facade(out)
    city_trees(out)
