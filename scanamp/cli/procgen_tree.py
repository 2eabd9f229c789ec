"""``scanamp procgen tree --species NAME|FILE.toml --height M --seed N --out DIR``: a tree of
Weber & Penn's model (:mod:`procgen.weber_penn`) with its QSM.

Writes into ``DIR``: ``tree.ply`` (coloured, every vertex labelled trunk, branch order or
leaf; ``labels.json`` names the labels), ``tree.qsm.csv`` (the woody skeleton as TreeQSM
cylinders) and ``preview.png``.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.config import Config, option

NAME = "tree"
GROUP = "procgen"
HELP = ("a tree of Weber & Penn's model for a species (shipped name or parameter file): "
        "labelled mesh, TreeQSM cylinders and a preview")

log = logging.getLogger(__name__)


@dataclass
class TreeConfig(Config):
    """Options of ``scanamp procgen tree``."""

    species: str = option("quaking_aspen", help="a shipped species (procgen/weber_penn/species"
                                                "/NAME.toml) or a parameter file FILE.toml")
    height: float | None = option(None, unit="m", range="(0, 200]",
                                  help="height of the tree (default: the species' Scale "
                                       "+- ScaleV)")
    season: str = option("summer", choices=("summer", "autumn", "winter"),
                         help="leaf colours: summer, autumn, or winter (deciduous leafless)")
    lod: str = option("full", choices=("full", "cards"),
                      help="leaves drawn one by one, or one card a twig (forests)")


CONFIG = TreeConfig


def add_arguments(p):
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same bytes)")
    p.add_argument("--no-preview", action="store_true", help="do not write preview.png")


def add_tree(plotter, mesh, title: str = "") -> None:
    """Add a :class:`procgen.weber_penn.TreeMesh` with its vertex colours to a pyvista
    plotter (the active subplot), on white, seen from a three-quarter view that fits it."""
    from core.meshes import make_mesh, to_pyvista

    poly = to_pyvista(make_mesh(mesh.vertices, mesh.triangles, vertex_colors=mesh.colors,
                                compute_normals=False))
    plotter.add_mesh(poly, scalars="rgb", rgb=True)
    if title:
        plotter.add_text(title, font_size=10, color="black")
    plotter.set_background("white")
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    c = (lo + hi) / 2
    span = float(max(hi - lo))
    plotter.camera_position = [(c[0] + 1.5 * span, c[1] - 1.5 * span, c[2] + 0.15 * span),
                               tuple(c), (0, 0, 1)]
    plotter.camera.view_angle = 30


def render_tree(mesh, path: Path, *, size=(640, 800)) -> Path:
    """Render a :class:`procgen.weber_penn.TreeMesh` with its vertex colours to a PNG
    (pyvista off-screen; matplotlib when there is no OpenGL)."""
    from core.io.image import write_image

    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import pyvista as pv

        pl = pv.Plotter(off_screen=True, window_size=size)
        add_tree(pl, mesh)
        img = pl.screenshot(return_img=True)
        pl.close()
    except Exception as exc:  # no OpenGL: the shared preview, one colour a part
        log.debug("pyvista preview failed (%s); using the parts' preview", exc)
        from core.meshes import make_mesh
        from scanamp.cli._procgen_common import render_preview

        parts = []
        for lab in np.unique(mesh.labels):
            v, f = mesh.part(int(lab))
            if len(f):
                parts.append((make_mesh(v, f), tuple(mesh.colors[f[:, 0]].mean(0))))
        return render_preview(parts, path, size=size)
    write_image(path, np.ascontiguousarray(img[..., :3]).astype(np.uint8))
    return path


def run(args, config: TreeConfig) -> int:
    from core.files import atomic_dir
    from core.io.mesh import write_labeled_mesh
    from core.io.qsm import write_qsm_csv
    from procgen.weber_penn import TREE_LABELS, grow, load_species, tree_mesh, tree_qsm

    params = load_species(config.species)       # bad species or file: exits 2, nothing written
    rng = np.random.default_rng(args.seed)
    tree = grow(params, height=config.height, rng=rng)
    mesh = tree_mesh(tree, rng=rng, season=config.season, lod=config.lod)
    qsm = tree_qsm(tree)
    with atomic_dir(args.out) as tmp:
        write_labeled_mesh(tmp / "tree.ply", mesh.vertices, mesh.triangles, colors=mesh.colors,
                           labels=mesh.labels, names=TREE_LABELS)
        write_qsm_csv(tmp / "tree.qsm.csv", qsm)
        if not args.no_preview:
            render_tree(mesh, tmp / "preview.png")
    log.info("wrote %s: %s %.1f m, %d stems, %d leaves, %d cylinders, %d triangles", args.out,
             params.species["common"], tree.height, tree.skeleton.n_stems, len(tree.leaves),
             len(qsm), len(mesh.triangles))
    return 0
