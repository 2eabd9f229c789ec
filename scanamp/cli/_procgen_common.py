"""Shared helpers of the ``scanamp procgen`` commands (not a command: leading underscore)."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from core.io.image import write_image

log = logging.getLogger(__name__)

MESH_OUT = (".ply", ".obj")


def add_output(parser, *, kind: str):
    parser.add_argument("--out", required=True, type=Path,
                        help=f"output file ({'PLY or OBJ' if kind == 'mesh' else 'PNG'})")
    parser.add_argument("--seed", type=int, default=0, help="random seed (same seed, same bytes)")
    if kind == "mesh":
        parser.add_argument("--no-preview", action="store_true",
                            help="do not write the FILE.preview.png render beside the mesh")


def labelled_companions(args) -> list[Path]:
    """What a command writing :func:`write_parts` output writes beside ``--out``."""
    extra = [args.out.with_name("labels.json")] if args.out.suffix.lower() == ".ply" else []
    return extra + ([] if args.no_preview else [preview_path(args.out)])


def check_out(path: Path, suffixes) -> Path:
    if path.suffix.lower() not in suffixes:
        raise ValueError(f"--out: expected a file ending in {', '.join(suffixes)}, "
                         f"got {str(path)!r}")
    return path


def preview_path(out: Path) -> Path:
    return out.with_name(out.stem + ".preview.png")


def render_preview(meshes, path: Path, *, size=(640, 480)) -> Path:
    """Render meshes off-screen to a PNG (pyvista/EGL; matplotlib when that fails).

    ``meshes`` is a list of ``(open3d mesh, rgb colour)``; a colour of None draws the
    mesh's vertex colours.
    """
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import pyvista as pv

        from core.meshes import to_pyvista

        pv.OFF_SCREEN = True
        plotter = pv.Plotter(off_screen=True, window_size=size)
        for mesh, color in meshes:  # colour None: the mesh's own vertex colours
            if len(mesh.triangles):
                plotter.add_mesh(to_pyvista(mesh), smooth_shading=True,
                                 **({"scalars": "rgb", "rgb": True} if color is None
                                    else {"color": color}))
        plotter.set_background("white")
        plotter.camera_position = "iso"
        plotter.reset_camera()
        img = plotter.screenshot(return_img=True)
        plotter.close()
    except Exception as exc:  # no OpenGL here: a plain matplotlib render instead
        log.debug("pyvista preview failed (%s); using matplotlib", exc)
        img = _matplotlib_preview(meshes, size)
    write_image(path, np.ascontiguousarray(img[..., :3]).astype(np.uint8))
    return path


def _matplotlib_preview(meshes, size):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure  # no pyplot: the caller's backend stays untouched
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    allv = []
    for mesh, color in meshes:
        v = np.asarray(mesh.vertices)
        f = np.asarray(mesh.triangles)
        if len(f):
            fc = color if color is not None else np.asarray(mesh.vertex_colors)[f].mean(axis=1)
            ax.add_collection3d(Poly3DCollection(v[f], facecolor=fc, edgecolor="none"))
            allv.append(v)
    if allv:
        v = np.vstack(allv)
        ax.auto_scale_xyz(v[:, 0], v[:, 1], v[:, 2])
    ax.set_axis_off()
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()




def write_parts(out: Path, parts, *, label_of: dict[str, str]) -> Path:
    """Write ``parts`` (``(mesh, kind, rgb)``) as one mesh: a ``.ply`` with a colour and a
    part label per vertex (``labels.json`` beside it names them, the ids of
    :data:`scanamp.amplify.labels.LABELS`); an ``.obj`` with the geometry only."""
    from core.io.mesh import write_labeled_mesh, write_mesh
    from core.meshes import compact, make_mesh, mesh_arrays
    from scanamp.amplify.labels import LABELS

    ids = {name: k for k, name in LABELS.items()}
    vs, fs, cs, ls, n = [], [], [], [], 0
    for mesh, kind, rgb in parts:
        v, f = mesh_arrays(mesh)
        used, tris = compact(f)  # drop unused vertices
        vs.append(v[used])
        fs.append(tris + n)
        cs.append(np.tile(np.asarray(rgb, float), (len(used), 1)))
        ls.append(np.full(len(used), ids[label_of[kind]]))
        n += len(used)
    v, f = np.vstack(vs), np.vstack(fs)
    if out.suffix.lower() == ".ply":
        return write_labeled_mesh(out, v, f, colors=np.vstack(cs), labels=np.concatenate(ls),
                                  names=LABELS)
    return write_mesh(out, make_mesh(v, f))
