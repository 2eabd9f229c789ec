"""Render the L-system example library, the seashell shapes, the shape-grammar plant and the
city to PNG with pyvista off-screen (EGL).

Usage: ``python docs/render_lsystem.py OUT_DIR [--small]`` (``--small`` writes the few
small images kept under ``docs/img``); ``python docs/render_lsystem.py OUT_DIR --abop``
writes only ``lsystem_abop_2_5.png``, the gallery of ABOP chapters 2-5 in docs/lsystem.md.
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import pyvista as pv  # noqa: E402

pv.OFF_SCREEN = True


def _poly(v, f):
    from core.meshes import make_mesh, to_pyvista  # the one conversion to pyvista

    return to_pyvista(make_mesh(v, f, compute_normals=False))


def render_mesh(path, v, f, *, color="tan", view="xz", size=(480, 480), colors=None):
    pl = pv.Plotter(off_screen=True, window_size=size)
    mesh = _poly(v, f)
    if colors is not None:
        mesh.point_data["rgb"] = (np.asarray(colors) * 255).astype(np.uint8)
        pl.add_mesh(mesh, scalars="rgb", rgb=True, smooth_shading=True)
    else:
        pl.add_mesh(mesh, color=color, smooth_shading=True)
    pl.set_background("white")
    if view == "xz":
        pl.view_xz(negative=False)
    elif view == "iso":
        pl.view_isometric()
    else:
        pl.view_xy()
    pl.camera.zoom(1.1)
    pl.screenshot(str(path))
    pl.close()


def render_lines(path, lines, *, size=(480, 480)):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    for pts in lines:
        ax.plot(pts[:, 0], pts[:, 2], "k-", lw=0.6)
    ax.set_aspect("equal")
    ax.axis("off")
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


ABOP_GALLERY = [
    ("abop_2_6a", "2.6a"), ("abop_2_6b", "2.6b"), ("abop_2_6c", "2.6c"), ("abop_2_6d", "2.6d"),
    ("abop_4_2_sunflower", "4.2 Vogel head, 1000"), ("abop_4_2_pineapple", "4.2 pineapple 8/13"),
    ("abop_2_7a", "2.7a"), ("abop_2_7b", "2.7b"), ("abop_2_7c", "2.7c"), ("abop_2_7d", "2.7d"),
    ("abop_3_mycelis", "3 Mycelis-like"), ("abop_3_lychnis", "3 Lychnis-like"),
    ("abop_2_8a", "2.8a"), ("abop_2_8b", "2.8b"), ("abop_2_8c", "2.8c"), ("abop_2_8d", "2.8d"),
    ("abop_5_compound_leaf", "5 compound leaf"), ("sunflower_300", "4.2 Vogel head, 300"),
]
"""(example, caption) in the gallery's order: three rows of six."""

_VIEWS = {"abop_4_2_sunflower": "top", "sunflower_300": "top", "abop_3_mycelis": "side",
          "abop_5_compound_leaf": "side", "abop_3_lychnis": "side"}
# mid-flowering Mycelis: the top buds open, the lower ones not yet; a 300-floret head
_STEPS = {"abop_3_mycelis": 36, "sunflower_300": 301}


def abop_gallery(out: Path) -> Path:
    """ABOP chapters 2-5 in a 3 x 6 grid: branches brown, leaflets green, flowers yellow."""
    from procgen.lsystem import derive, interpret, load_grammar, to_mesh

    pl = pv.Plotter(off_screen=True, shape=(3, 6), window_size=(1500, 780), border=False)
    for k, (name, caption) in enumerate(ABOP_GALLERY):
        g = load_grammar("abop_4_2_sunflower" if name == "sunflower_300" else name)
        r = interpret(derive(g, _STEPS.get(name)), g)
        pl.subplot(k // 6, k % 6)
        mesh = to_mesh(r, sides=6)
        poly = _poly(np.asarray(mesh.vertices), np.asarray(mesh.triangles))
        poly.point_data["rgb"] = (np.asarray(mesh.vertex_colors) * 255).astype(np.uint8)
        pl.add_mesh(poly, scalars="rgb", rgb=True, smooth_shading=True)
        petals = r.colors == 2                      # flowers: yellow petal tips
        if petals.any():
            pl.add_points(r.ends[petals], color=(0.98, 0.8, 0.1), point_size=6,
                          render_points_as_spheres=True)
        pl.add_text(caption, font_size=9, color="black")
        pl.set_background("white")
        view = _VIEWS.get(name, "iso")
        if view == "top":
            pl.view_xy()
        elif view == "side":
            pl.view_xz()
        else:
            pl.view_xz()
            pl.camera.elevation = 15
            pl.camera.azimuth = 30
        pl.reset_camera()
        pl.camera.zoom(1.15)
    path = out / "lsystem_abop_2_5.png"
    pl.screenshot(str(path))
    pl.close()
    return path


def main(argv):
    from procgen.lsystem import derive, example_names, interpret, load_grammar, to_mesh

    out = Path(argv[0] if argv else "renders")
    small = "--small" in argv
    out.mkdir(parents=True, exist_ok=True)
    if "--abop" in argv:
        sys.stdout.write(f"{abop_gallery(out)}\n")
        return
    curves = {"koch_snowflake", "quadratic_koch_island", "dragon", "sierpinski_gasket"}
    for name in example_names():
        g = load_grammar(name)
        s = derive(g, rng=np.random.default_rng(1))
        r = interpret(s, g)
        if len(r) == 0:
            continue
        if name in curves:
            render_lines(out / f"lsys_{name}.png", r.polylines())
        else:
            mesh = to_mesh(r, sides=6, min_radius=0.15 if name != "parametric_tree" else 0.0)
            v, f = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
            render_mesh(out / f"lsys_{name}.png", v, f, color="sienna",
                        view="iso" if name == "parametric_tree" else "xz")
    from procgen.shells import SHAPES, cortie_shell, helicospiral_shell

    for name in SHAPES:
        v, f = cortie_shell(name, n_theta=300, n_s=32)
        render_mesh(out / f"shell_{name}.png", v, f, color="wheat", view="iso")
    v, f = helicospiral_shell(spire=1.5)
    render_mesh(out / "shell_helicospiral.png", v, f, color="wheat", view="iso")
    try:
        from procgen.shape_grammar import plant_mesh

        v, f = plant_mesh(np.random.default_rng(3))
        render_mesh(out / "shape_grammar_plant.png", v, f, color="olivedrab", view="xz")
    except ImportError:
        pass
    try:
        from procgen.city import generate_city

        city = generate_city(np.random.default_rng(0))
        render_mesh(out / "city.png", city.vertices, city.triangles, color="lightgray",
                    view="iso", size=(640, 640))
    except ImportError:
        pass
    if small:
        for p in out.glob("*.png"):
            if p.stat().st_size > 200_000:
                p.unlink()


if __name__ == "__main__":
    main(sys.argv[1:])
