"""Loading scans from what users have: range images, point clouds, meshes, E57 files,
folders of them and scanalyze ``.conf`` files (the file formats are :mod:`core.io.range`,
:mod:`core.io.e57` and :mod:`core.io.mesh`).

- a PLY with a ``range_grid`` element: a range image, triangulated on its grid
  (:func:`reconstruct.scans.scan.scan_from_grid`);
- any other PLY, OBJ, PCD, STL, OFF or XYZ file: a point cloud or mesh seen from the
  origin of its frame (:func:`reconstruct.scans.scan.scan_from_points`);
- an E57 file: every scan in it, named ``FILE[i]``; a structured scan (row and column
  indices) as a range image seen from its origin; the file's pose kept as
  ``model_from_scan`` (an initial guess at most);
- a ``.conf``: the scans it names (a missing one is an error naming the ``.conf``);
- a folder: its ``scans/`` subfolder when it has one (a ``scanamp capture scans`` output),
  else the scan files directly in it, in name order.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from core.io.range import RangeGrid, conf_files, is_range_grid, read_range_grid
from core.validate import InputError
from reconstruct.scans.scan import RangeScan, scan_from_grid, scan_from_points

__all__ = ["load_scans", "check_scans", "scan_files", "SCAN_SUFFIXES"]

#: the suffixes read as scans (a folder's other files are left alone)
SCAN_SUFFIXES = (".ply", ".obj", ".pcd", ".e57", ".stl", ".off", ".xyz")


def scan_files(paths: Iterable[str | os.PathLike]) -> list[Path]:
    """The scan files that ``paths`` (files, folders, ``.conf`` files) stand for, in order."""
    out: list[Path] = []
    for raw in paths:
        path = Path(raw)
        if path.is_dir():
            folder = path / "scans" if (path / "scans").is_dir() else path
            out += sorted(f for f in folder.iterdir()
                          if f.is_file() and f.suffix.lower() in SCAN_SUFFIXES)
        elif path.suffix.lower() == ".conf":
            out += [f for f, _ in conf_files(path)]
        elif not path.exists():
            raise InputError("file not found", path=path)
        elif path.suffix.lower() not in SCAN_SUFFIXES:
            raise InputError(f"expected a scan file ({', '.join(SCAN_SUFFIXES)}), a .conf or "
                             f"a folder, got {path.suffix!r}", path=path)
        else:
            out.append(path)
    return out


def _load_file(path: Path, options: dict) -> list[RangeScan]:
    from core.io.mesh import read_geometry

    suffix = path.suffix.lower()
    if suffix == ".e57":
        return _load_e57(path, options)
    if suffix == ".ply" and is_range_grid(path):
        return [scan_from_grid(read_range_grid(path), name=path.name, **options)]
    geo = read_geometry(path)
    if hasattr(geo, "triangles"):
        pts, tris = np.asarray(geo.vertices), np.asarray(geo.triangles)
        normals = np.asarray(geo.vertex_normals) if geo.has_vertex_normals() else None
    else:
        pts, tris = np.asarray(geo.points), None
        normals = np.asarray(geo.normals) if geo.has_normals() else None
    if normals is not None and not np.all(np.isfinite(normals)):
        normals = None
    return [scan_from_points(pts, normals, name=path.name, triangles=tris, path=path)]


def _load_e57(path: Path, options: dict) -> list[RangeScan]:
    from core.io.e57 import read_e57

    out = []
    for i, e in enumerate(read_e57(path)):
        name = f"{path.name}[{i}]"
        index = e.grid()
        if index is not None:
            scan = scan_from_grid(RangeGrid(e.points, index, e.intensity, path), name=name,
                                  **options)
        else:
            scan = scan_from_points(e.points, name=name, path=path)
        scan.model_from_scan = e.model_from_scan
        out.append(scan)
    return out


def check_scans(scans: Sequence[RangeScan], *, source=None, min_scans: int = 2) -> None:
    """InputError unless there are at least ``min_scans`` scans, each with points.

    ``source`` names the input in the message (the file or folder given).
    """
    for s in scans:
        if not len(s.points):
            raise InputError("the scan has no points", path=s.path or s.name, field="points")
    if len(scans) < min_scans:
        names = ", ".join(s.name for s in scans) or "none"
        raise InputError(f"expected at least {min_scans} scans to register, got {len(scans)} "
                         f"({names})", path=source, field="scans")


def load_scans(paths: str | os.PathLike | Iterable[str | os.PathLike], *, min_scans: int = 2,
               max_jump: float = 4.0, max_sight_deg: float = 80.0,
               edge_steps: float = 3.0) -> list[RangeScan]:
    """Read every scan that ``paths`` stand for (module docstring) as :class:`RangeScan`.

    Parameters
    ----------
    paths : path or sequence of paths
        Files, folders, E57 files, ``.conf`` files.
    min_scans : int
        Fewer scans than this raise InputError (``scans``); 0 to accept any number.
    max_jump, max_sight_deg, edge_steps
        How range images are triangulated (:func:`reconstruct.scans.scan.scan_from_grid`).

    Raises
    ------
    InputError
        Naming the file and field: a range grid whose size disagrees with its cells
        (``range_grid``), a cell index out of range, a scan with no points, an E57 scan
        without points (``data3D[i] (NAME)``), a ``.conf`` naming a missing file, fewer
        than ``min_scans`` scans.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    paths = list(paths)
    options = {"max_jump": max_jump, "max_sight_deg": max_sight_deg, "edge_steps": edge_steps}
    scans: list[RangeScan] = []
    for f in scan_files(paths):
        scans += _load_file(f, options)
    names = [s.name for s in scans]
    for s in scans:                  # the same file name in two folders: use the path
        if names.count(s.name) > 1 and s.path is not None and not s.name.startswith(str(s.path)):
            s.name = str(s.path) + s.name[len(s.path.name):]
    source = paths[0] if len(paths) == 1 else ", ".join(str(p) for p in paths)
    check_scans(scans, source=source, min_scans=min_scans)
    return scans
