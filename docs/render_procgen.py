"""Render the city, its street patterns, facades of its split grammars (docs/city.md), and
a gallery of 12 plants from the shape grammar (docs/lsystem.md), coloured by part, with
pyvista off-screen (EGL).

Usage: ``python docs/render_procgen.py OUT_DIR`` (writes ``city.png``,
``city_patterns.png``, ``city_facades.png`` and ``plant_gallery.png``; the copies under
``docs/img`` come from here).
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
    from scanamp.cli.procgen_city import COLORS

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


def city_patterns(out: Path, seed: int = 0) -> Path:
    """The four street patterns in plan: highways, streets, lots and buildings."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from procgen.city import CityConfig, generate_city, street_statistics

    fig, axes = plt.subplots(1, 4, figsize=(16, 4.4))
    for ax, pattern in zip(axes, ("grid", "radial", "organic", "elevation"), strict=True):
        c = generate_city(np.random.default_rng(seed),
                          CityConfig(size=1200, max_segments=300, pattern=pattern))
        half = c.config.size / 2
        g = np.linspace(-half, half, 200)
        X, Y = np.meshgrid(g, g)
        P = np.stack([X.ravel(), Y.ravel()], 1)
        if pattern == "elevation":
            ax.contour(X, Y, c.maps.elevation(P).reshape(X.shape), levels=12,
                       colors="0.75", linewidths=0.6)
        ax.contourf(X, Y, c.water(P).reshape(X.shape).astype(float), levels=[0.5, 1.5],
                    colors=["#8ab4d8"])
        ax.contourf(X, Y, c.park(P).reshape(X.shape).astype(float), levels=[0.5, 1.5],
                    colors=["#a8cf8e"])
        for lot in c.lots:
            ax.fill(*lot.polygon.exterior.xy, color="#f1e9d8", lw=0)
        for b in c.buildings:
            ax.fill(*np.vstack([b.footprint, b.footprint[:1]]).T, color="#b5532f", lw=0)
        for (i, j), hw in zip(c.edges, c.highway, strict=True):
            ax.plot(*c.nodes[[i, j]].T, "k-", lw=1.8 if hw else 0.7)
        s = street_statistics(c.nodes, c.edges)
        ax.set_title(f"{pattern}: phi {s['orientation_order']:.2f}, degree "
                     f"{s['mean_degree']:.2f}\ndead ends {100 * s['dead_end_share']:.0f} %, "
                     f"circuity {s['circuity']:.3f}", fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlim(-half, half)
        ax.set_ylim(-half, half)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    path = out / "city_patterns.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def city_facades(out: Path) -> Path:
    """One building of each shipped grammar, and each roof kind, seen from the street."""
    from procgen.city import LABELS, build, load_grammar
    from scanamp.cli.procgen_city import COLORS

    cases = [("residential", 3, 12.0, 10.0, "gable"), ("residential", 2, 9.0, 9.0, "hip"),
             ("residential", 4, 15.0, 11.0, "flat"), ("office", 9, 16.0, 14.0, "flat")]
    pl = pv.Plotter(off_screen=True, shape=(1, 4), window_size=(1600, 520), border=False)
    for k, (name, floors, w, d, roof) in enumerate(cases):
        g = load_grammar(name)
        g.attributes = {**g.attributes, "roof": roof, "roof_pitch": 35.0}
        geo = build(g, np.array([[0.0, 0], [w, 0], [w, d], [0, d]]), floors=floors,
                    rng=np.random.default_rng(k))
        v, f, lab = geo.mesh()
        rgb = np.array([COLORS[e] for e in LABELS])[lab]
        vv = v[f].reshape(-1, 3)
        pl.subplot(0, k)
        pl.add_mesh(_colored(vv, np.arange(len(vv)).reshape(-1, 3), np.repeat(rgb, 3, axis=0)),
                    scalars="rgb", rgb=True)
        pl.add_text(f"{name}.toml: {floors} floors, {roof} roof", font_size=9)
        pl.set_background("white")
        span = max(w, d, geo.ridge_height)
        pl.camera_position = [(w * 0.1, -2.4 * span, 0.7 * geo.ridge_height),
                              (w / 2, d / 2, 0.5 * geo.ridge_height), (0, 0, 1)]
    path = out / "city_facades.png"
    pl.screenshot(str(path))
    pl.close()
    return path


def plant_gallery(out: Path, seeds=range(12)) -> Path:
    from procgen.shape_grammar import plant_mesh
    from scanamp.cli.procgen_plant import BARK, LEAF

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
    which = argv[1:] or ["city", "city_patterns", "city_facades", "plant_gallery"]
    for name in which:
        sys.stdout.write(f"{globals()[name](out)}\n")


if __name__ == "__main__":
    main(sys.argv[1:])
