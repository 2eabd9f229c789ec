"""``scanamp mesh clean MESH --out CLEAN.ply``: floaters off, holes closed, remeshed,
denoised and oriented (:func:`reconstruct.surface.clean.clean_mesh`); ``CLEAN.report.json``
says what was removed and filled."""

from __future__ import annotations

import logging
from pathlib import Path

from reconstruct.surface.clean import CleanOptions

GROUP = "mesh"
NAME = "clean"
OUTPUT = "file"
HELP = ("clean a reconstructed mesh: drop floaters, close holes, remesh, denoise, orient "
        "(pymeshlab); writes the mesh and FILE.report.json")
CONFIG = CleanOptions

log = logging.getLogger(__name__)


def _report_path(out: Path) -> Path:
    return out.with_name(out.stem + ".report.json")


def companions(args, config=None):
    return [_report_path(args.out)]


def add_arguments(p):
    p.add_argument("mesh", type=Path, help="the mesh to clean (PLY, OBJ, ...)")
    p.add_argument("--out", required=True, type=Path, help="cleaned mesh file to write")


def run(args, config: CleanOptions) -> int:
    from core.files import write_json
    from core.io.mesh import MESH_SUFFIXES, read_mesh, write_mesh
    from core.validate import InputError
    from reconstruct.surface.clean import clean_mesh

    if args.out.suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"--out: expected a suffix in {', '.join(MESH_SUFFIXES)}, "
                         f"got {args.out.suffix!r}")
    mesh = read_mesh(args.mesh)
    if len(mesh.triangles) == 0:
        raise InputError("the mesh has no triangles", path=args.mesh)
    out, report = clean_mesh(mesh, config)
    write_mesh(args.out, out)
    write_json(_report_path(args.out), {"input": str(args.mesh), **report})
    log.info("wrote %s (%d floaters removed, boundary edges %d -> %d)", args.out,
             report["floaters"]["removed"], report["holes"]["boundary_edges_before"],
             report["holes"]["boundary_edges_after"])
    return 0
