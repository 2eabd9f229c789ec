"""Mesh and point-cloud files: the one place that knows these formats.

Meshes: PLY, OBJ, glTF/GLB (``.gltf``/``.glb``), STL, OFF. Point clouds: PLY, PCD, XYZ.
Polylines (curves): OBJ ``l`` records, PLY edges. Every writer is atomic. Images are
:mod:`core.image_io`.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError

__all__ = ["read_mesh", "write_mesh", "read_points", "write_points",
           "read_geometry", "write_polylines", "MESH_SUFFIXES", "POINT_SUFFIXES",
           "POLYLINE_SUFFIXES"]

MESH_SUFFIXES = (".ply", ".obj", ".gltf", ".glb", ".stl", ".off")
# open3d 0.20 writes .glb without its binary chunk (unreadable by open3d and VTK).
WRITE_SUFFIXES = (".ply", ".obj", ".gltf", ".stl", ".off")
POINT_SUFFIXES = (".ply", ".pcd", ".xyz", ".xyzn", ".xyzrgb", ".pts")
POLYLINE_SUFFIXES = (".obj", ".ply")


def read_mesh(path: str | os.PathLike):
    """Read a triangle mesh; InputError naming the file when missing, unreadable or empty."""
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise InputError(f"expected a mesh file ({', '.join(MESH_SUFFIXES)}), got {path.suffix!r}",
                         path=path)
    mesh = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False, print_progress=False)
    if len(mesh.vertices) == 0:
        raise InputError("no vertices read (empty or corrupt mesh file)", path=path)
    return mesh


def write_mesh(path: str | os.PathLike, mesh, *, ascii: bool = False):
    """Write ``mesh`` atomically; the format follows the suffix."""
    import open3d as o3d

    path = Path(path)
    if path.suffix.lower() not in WRITE_SUFFIXES:
        raise ValueError(f"path: expected a suffix in {WRITE_SUFFIXES}, got {path.suffix!r}"
                         + (" (open3d 0.20 writes broken .glb files; use .gltf)"
                            if path.suffix.lower() == ".glb" else ""))
    # Write into a temporary folder under the final name (OBJ names its .mtl and
    # textures after the file), then move every file into place.
    import shutil
    import tempfile

    path.parent.mkdir(parents=True, exist_ok=True)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{path.stem}.tmp-", dir=path.parent))
    try:
        target = tmpdir / path.name
        ok = o3d.io.write_triangle_mesh(str(target), mesh, write_ascii=ascii,
                                        print_progress=False)
        if not ok:
            raise RuntimeError(f"open3d failed to write {path}")
        for f in sorted(tmpdir.iterdir()):
            if f.name != path.name:
                os.replace(f, path.parent / f.name)
        os.replace(target, path)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
    return path


def write_polylines(path: str | os.PathLike, polylines) -> Path:
    """Write curves atomically: OBJ (one ``l`` record per polyline) or ASCII PLY (vertices
    and ``edge`` elements, which open3d reads as a LineSet).

    Parameters
    ----------
    path : path-like
        ``.obj`` or ``.ply``.
    polylines : sequence of (k, 3) float64
        Each with at least 2 points.
    """
    from core.validate import check_array

    path = Path(path)
    if path.suffix.lower() not in POLYLINE_SUFFIXES:
        raise ValueError(f"path: expected a suffix in {POLYLINE_SUFFIXES}, got {path.suffix!r}")
    lines = [check_array(p, f"polylines[{i}]", shape=(None, 3), min_rows=2)
             for i, p in enumerate(polylines)]
    pts = np.vstack(lines) if lines else np.empty((0, 3))
    starts = np.cumsum([0] + [len(p) for p in lines])
    with atomic_file(path) as tmp, open(tmp, "w") as fh:
        if path.suffix.lower() == ".obj":
            fh.write("# polylines written by scanamp\n")
            np.savetxt(fh, pts, fmt="v %.9g %.9g %.9g")
            for a, b in zip(starts[:-1], starts[1:], strict=True):
                fh.write("l " + " ".join(str(i + 1) for i in range(a, b)) + "\n")
        else:
            edges = np.concatenate([np.stack([np.arange(a, b - 1), np.arange(a + 1, b)], -1)
                                    for a, b in zip(starts[:-1], starts[1:], strict=True)]
                                   ) if lines else np.empty((0, 2), np.int64)
            fh.write(f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\nproperty double x\n"
                     f"property double y\nproperty double z\nelement edge {len(edges)}\n"
                     "property int vertex1\nproperty int vertex2\nend_header\n")
            np.savetxt(fh, pts, fmt="%.9g %.9g %.9g")
            np.savetxt(fh, edges, fmt="%d %d")
    return path


def read_points(path: str | os.PathLike):
    """Read a point cloud (``open3d.geometry.PointCloud``); InputError when empty."""
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    pcd = o3d.io.read_point_cloud(str(path))
    if len(pcd.points) == 0:
        raise InputError("no points read (empty or corrupt point file)", path=path)
    return pcd


def write_points(path: str | os.PathLike, points: np.ndarray, *, normals=None, colors=None):
    """Write ``points (n, 3)`` (optionally normals and colours in [0, 1]) as a point cloud.

    An empty cloud is written as a valid PLY with no vertices (open3d refuses to write
    one); other formats need at least one point.
    """
    import open3d as o3d

    if len(points) == 0:
        return _write_empty_ply(path, normals=normals is not None, colors=colors is not None)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, np.float64)))
    if normals is not None:
        pcd.normals = o3d.utility.Vector3dVector(np.asarray(normals, np.float64))
    if colors is not None:
        pcd.colors = o3d.utility.Vector3dVector(np.clip(np.asarray(colors, np.float64), 0, 1))
    with atomic_file(path) as tmp:
        if not o3d.io.write_point_cloud(str(tmp), pcd, print_progress=False):
            raise RuntimeError(f"open3d failed to write {path}")
    return Path(path)


def _write_empty_ply(path, *, normals: bool, colors: bool) -> Path:
    if Path(path).suffix.lower() != ".ply":
        raise ValueError(f"points: an empty cloud can only be written as .ply, got {path}")
    props = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals else [])
    header = ["ply", "format binary_little_endian 1.0", "comment written by core.mesh_io",
              "element vertex 0", *(f"property double {p}" for p in props),
              *([f"property uchar {c}" for c in ("red", "green", "blue")] if colors else []),
              "end_header"]
    with atomic_file(path) as tmp:
        tmp.write_bytes(("\n".join(header) + "\n").encode("ascii"))
    return Path(path)


@contextlib.contextmanager
def _quiet_native_stderr():
    """Silence file descriptor 2 (C libraries such as RPly print there directly)."""
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # pragma: no cover - no fd 2 at all
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def read_geometry(path: str | os.PathLike):
    """Read a mesh or a point cloud, decided by whether the file has faces.

    Mesh suffixes (:data:`MESH_SUFFIXES`) are read as a triangle mesh; one with
    no triangles (a PLY of vertices only) is returned as a point cloud instead,
    with its normals and colours. Point suffixes (:data:`POINT_SUFFIXES`: PCD,
    XYZ, ...) are read as a point cloud.

    Returns
    -------
    open3d.geometry.TriangleMesh or open3d.geometry.PointCloud

    Raises
    ------
    InputError
        Naming the file: missing, unsupported suffix, corrupt, or empty.
    """
    import open3d as o3d

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES + POINT_SUFFIXES:
        allowed = ", ".join(sorted(set(MESH_SUFFIXES + POINT_SUFFIXES)))
        raise InputError(f"expected a mesh or point file ({allowed}), got {suffix!r}", path=path)
    quiet = o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error)
    with quiet, _quiet_native_stderr():
        if suffix in MESH_SUFFIXES:
            mesh = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False,
                                             print_progress=False)
            if len(mesh.triangles) > 0:
                return mesh
            if suffix != ".ply":
                if len(mesh.vertices) == 0:
                    raise InputError("no vertices read (empty or corrupt mesh file)", path=path)
                pcd = o3d.geometry.PointCloud(mesh.vertices)
                if mesh.has_vertex_normals():
                    pcd.normals = mesh.vertex_normals
                return pcd
        pcd = o3d.io.read_point_cloud(str(path))
    if len(pcd.points) == 0:
        raise InputError("no points read (empty or corrupt file)", path=path)
    return pcd
