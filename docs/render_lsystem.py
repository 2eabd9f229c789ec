"""Render the L-system example library, the seashell shapes, the shape-grammar plant and the
city to PNG with pyvista off-screen (EGL).

Usage: ``python docs/render_lsystem.py OUT_DIR [--small]`` (``--small`` writes the few
small images kept under ``docs/img``).
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


def main(argv):
    from procgen.lsystem import derive, example_names, interpret, load_grammar, to_mesh

    out = Path(argv[0] if argv else "renders")
    small = "--small" in argv
    out.mkdir(parents=True, exist_ok=True)
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
