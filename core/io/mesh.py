"""Mesh and point-cloud files: the one place that knows these formats.

Meshes: PLY, OBJ, glTF/GLB (``.gltf``/``.glb``), STL, OFF. Point clouds: PLY, PCD, XYZ.
Polylines (curves): OBJ ``l`` records, PLY edges. Every writer is atomic. Images are
:mod:`core.io.image`.
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
           "POLYLINE_SUFFIXES", "write_labeled_mesh", "read_labeled_mesh", "native_output"]

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
    said: list[str] = []
    with native_output(said):
        mesh = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False,
                                         print_progress=False)
    if len(mesh.vertices) == 0:
        raise InputError(f"no vertices read (empty or corrupt mesh file){_because(said)}",
                         path=path)
    _check_complete(path, "vertex", len(mesh.vertices))
    _check_complete(path, "face", len(mesh.triangles))
    _check_finite(path, np.asarray(mesh.vertices))
    return mesh


def _check_finite(path: Path, vertices: np.ndarray) -> None:
    bad = int(np.count_nonzero(~np.isfinite(vertices).all(axis=1)))
    if bad:
        raise InputError(f"vertices: {bad} with NaN or infinite coordinates", path=path)


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

    from core.files import hold, temp_prefix

    path.parent.mkdir(parents=True, exist_ok=True)
    with hold(path, wait=True):
        tmpdir = Path(tempfile.mkdtemp(prefix=temp_prefix(path), dir=path.parent))
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


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


def write_labeled_mesh(path: str | os.PathLike, vertices: np.ndarray, triangles: np.ndarray, *,
                       colors: np.ndarray | None = None, labels: np.ndarray | None = None,
                       names: dict[int, str] | None = None) -> Path:
    """Write a triangle mesh whose vertices carry a colour and an integer part label.

    The PLY (binary little-endian) has vertex properties ``x y z`` (double),
    ``red green blue`` (uchar) and ``label`` (int), which MeshLab, Open3D (colours)
    and plyfile read. ``names`` (label -> part name) goes to ``labels.json`` beside
    the mesh, written atomically too.

    Parameters
    ----------
    vertices : (n, 3) float
    triangles : (m, 3) int
    colors : (n, 3) float in [0, 1] or uint8, optional (default mid grey)
    labels : (n,) int, optional (default 0)
    names : dict, optional

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> v = np.eye(3); f = np.array([[0, 1, 2]])
    >>> _ = write_labeled_mesh(d / "m.ply", v, f, labels=np.array([0, 1, 1]),
    ...                        names={0: "ground", 1: "object"})
    >>> m = read_labeled_mesh(d / "m.ply")
    >>> m["labels"].tolist(), m["names"], m["triangles"].tolist()
    ([0, 1, 1], {0: 'ground', 1: 'object'}, [[0, 1, 2]])
    """
    import json

    from core.validate import check_array

    path = Path(path)
    if path.suffix.lower() != ".ply":
        raise ValueError(f"path: a labelled mesh is written as .ply, got {path.suffix!r}")
    v = check_array(vertices, "vertices", shape=(None, 3), finite=True).astype("<f8")
    f = check_array(triangles, "triangles", shape=(None, 3), dtype=np.int64).astype("<i4")
    n = len(v)
    if len(f) and (f.min() < 0 or f.max() >= n):
        raise ValueError(f"triangles: indices must lie in [0, {n})")
    if colors is None:
        rgb = np.full((n, 3), 128, np.uint8)
    else:
        c = check_array(colors, "colors", shape=(n, 3), dtype=None)
        rgb = (c if c.dtype == np.uint8
               else np.clip(np.round(np.asarray(c, np.float64) * 255), 0, 255).astype(np.uint8))
    lab = np.zeros(n, "<i4") if labels is None else check_array(
        labels, "labels", shape=(n,), dtype=np.int64).astype("<i4")
    vdt = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("red", "u1"), ("green", "u1"),
                    ("blue", "u1"), ("label", "<i4")])
    vrec = np.empty(n, vdt)
    vrec["x"], vrec["y"], vrec["z"] = v.T
    vrec["red"], vrec["green"], vrec["blue"] = rgb.T
    vrec["label"] = lab
    frec = np.empty(len(f), np.dtype([("n", "u1"), ("idx", "<i4", (3,))]))
    frec["n"], frec["idx"] = 3, f
    header = ("ply\nformat binary_little_endian 1.0\ncomment written by scanamp\n"
              f"element vertex {n}\n" + "".join(
                  f"property {t} {k}\n" for k, t in (("x", "double"), ("y", "double"),
                                                    ("z", "double"), ("red", "uchar"),
                                                    ("green", "uchar"), ("blue", "uchar"),
                                                    ("label", "int")))
              + f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    with atomic_file(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(header.encode("ascii"))
            fh.write(vrec.tobytes())
            fh.write(frec.tobytes())
    if names is not None:
        with atomic_file(path.with_name("labels.json")) as tmp:
            tmp.write_text(json.dumps({str(int(k)): str(v) for k, v in sorted(names.items())},
                                      indent=2) + "\n")
    return path


def read_labeled_mesh(path: str | os.PathLike) -> dict:
    """Read a PLY triangle mesh with its per-vertex colour and label, if present.

    Reads binary little-endian and ASCII PLY with scalar vertex properties and a
    ``vertex_indices`` face list of triangles (as :func:`write_labeled_mesh` writes).

    Returns
    -------
    dict
        ``vertices (n, 3) float64``, ``triangles (m, 3) int64``, ``colors (n, 3) uint8``
        or None, ``labels (n,) int64`` or None, ``names`` from ``labels.json`` beside
        the file (label -> name) or None.
    """
    import json

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    data = path.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise InputError("not a PLY file (no 'ply' magic or no end_header)", path=path)
    body_start = data.index(b"\n", end) + 1
    fmt, elements = None, []
    for line in data[:end].decode("ascii", "replace").splitlines():
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append([w[1], int(w[2]), []])
        elif w[0] == "property" and elements:
            elements[-1][2].append(w[1:])
    if fmt not in ("binary_little_endian", "ascii"):
        raise InputError(f"format: {fmt!r} is not supported (binary_little_endian or ascii)",
                         path=path)
    out = {"vertices": None, "triangles": np.empty((0, 3), np.int64), "colors": None,
           "labels": None, "names": None}
    try:
        if fmt == "ascii":
            _read_ascii_elements(data[body_start:], elements, out)
        else:
            _read_binary_elements(data, body_start, elements, out)
    except (ValueError, IndexError, KeyError) as exc:
        raise InputError(f"truncated or malformed PLY body ({exc})", path=path) from None
    if out["vertices"] is None or not len(out["vertices"]):
        raise InputError("no vertices read (empty or corrupt mesh file)", path=path)
    names_file = path.with_name("labels.json")
    if names_file.is_file():
        try:
            out["names"] = {int(k): v for k, v in json.loads(names_file.read_text()).items()}
        except (ValueError, AttributeError) as exc:
            raise InputError(f"expected a JSON object of label -> name ({exc})",
                             path=names_file) from None
    return out


def _store_vertices(rec, out) -> None:
    names = rec.dtype.names
    out["vertices"] = np.stack([rec["x"], rec["y"], rec["z"]], -1).astype(np.float64)
    if all(c in names for c in ("red", "green", "blue")):
        out["colors"] = np.stack([rec["red"], rec["green"], rec["blue"]], -1).astype(np.uint8)
    if "label" in names:
        out["labels"] = rec["label"].astype(np.int64)


def _read_binary_elements(data: bytes, pos: int, elements, out) -> None:
    for name, count, props in elements:
        if props and props[0][0] == "list":
            _, ctype, itype, _ = props[0]
            c, it = np.dtype("<" + _PLY_TYPES[ctype]), np.dtype("<" + _PLY_TYPES[itype])
            if name == "face" and count:
                probe = int(np.frombuffer(data, c, 1, pos)[0])
                dt = np.dtype([("n", c), ("idx", it, (probe,))])
                rec = np.frombuffer(data, dt, count, pos)
                if probe != 3 or np.any(rec["n"] != 3):
                    raise ValueError("only triangle faces are supported")
                out["triangles"] = rec["idx"].astype(np.int64)
                pos += dt.itemsize * count
            elif count:
                raise ValueError(f"list element {name!r} is not supported")
            continue
        dt = np.dtype([(p[1], "<" + _PLY_TYPES[p[0]]) for p in props])
        rec = np.frombuffer(data, dt, count, pos)
        pos += dt.itemsize * count
        if name == "vertex":
            _store_vertices(rec, out)


def _read_ascii_elements(body: bytes, elements, out) -> None:
    lines = body.decode("ascii").splitlines()
    row = 0
    for name, count, props in elements:
        chunk = lines[row:row + count]
        row += count
        if len(chunk) != count:
            raise ValueError(f"{name}: expected {count} rows, found {len(chunk)}")
        if props and props[0][0] == "list":
            if name == "face" and count:
                idx = np.array([[int(t) for t in ln.split()] for ln in chunk])
                if idx.shape[1] != 4 or np.any(idx[:, 0] != 3):
                    raise ValueError("only triangle faces are supported")
                out["triangles"] = idx[:, 1:].astype(np.int64)
            continue
        arr = np.array([[float(t) for t in ln.split()] for ln in chunk]).reshape(count, len(props))
        rec = np.empty(count, [(p[1], "<" + _PLY_TYPES[p[0]]) for p in props])
        for i, p in enumerate(props):
            rec[p[1]] = arr[:, i]
        if name == "vertex":
            _store_vertices(rec, out)


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
    said: list[str] = []
    with native_output(said):
        pcd = o3d.io.read_point_cloud(str(path))
    if len(pcd.points) == 0:
        raise InputError(f"no points read (empty or corrupt point file){_because(said)}",
                         path=path)
    _check_complete(path, "vertex", len(pcd.points))
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
    header = ["ply", "format binary_little_endian 1.0", "comment written by core.io.mesh",
              "element vertex 0", *(f"property double {p}" for p in props),
              *([f"property uchar {c}" for c in ("red", "green", "blue")] if colors else []),
              "end_header"]
    with atomic_file(path) as tmp:
        tmp.write_bytes(("\n".join(header) + "\n").encode("ascii"))
    return Path(path)


@contextlib.contextmanager
def native_output(said: list[str], fds: tuple[int, ...] = (2,), *, open3d: bool = True):
    """Capture file descriptors ``fds`` (C libraries such as RPly and PoissonRecon print
    there directly) and Open3D's own warnings; what they said is appended to ``said``,
    one string per line, so that the caller can log it or put it in a one-line error
    instead of a stray line on the terminal. ``open3d=False`` for a block that calls no
    Open3D: importing it only to quiet it costs seconds."""
    import tempfile

    if open3d:
        import open3d as o3d

        quiet = o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error)
    else:
        quiet = contextlib.nullcontext()
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        saved = [os.dup(fd) for fd in fds]
    except OSError:  # pragma: no cover - no such descriptor at all
        yield
        return
    with tempfile.TemporaryFile() as sink, quiet:
        for fd in fds:
            os.dup2(sink.fileno(), fd)
        try:
            yield
        finally:
            for fd, old in zip(fds, saved, strict=True):
                os.dup2(old, fd)
                os.close(old)
            sink.seek(0)
            text = sink.read().decode("utf-8", "replace")
            said.extend(ln.strip() for ln in text.splitlines() if ln.strip())


def _ply_header_counts(path: Path) -> dict[str, int]:
    """``{"vertex": n, "face": m}`` as a PLY header declares them (empty if not a PLY).

    A binary PLY shorter than its header says (each face at least a triangle) is
    reported as truncated: Open3D reads such a file without a word, padding with zeros.
    """
    if path.suffix.lower() != ".ply":
        return {}
    with open(path, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply"):
        return {}
    if end < 0:
        raise InputError("truncated or corrupt PLY: its header has no end_header", path=path)
    counts, sizes, binary = {}, {}, False
    for line in head[:end].decode("ascii", "replace").splitlines():
        w = line.split()
        if len(w) == 3 and w[0] == "element" and w[2].isdigit():
            counts[w[1]] = int(w[2])
            sizes[w[1]] = 0
        elif w[:1] == ["format"]:
            binary = len(w) > 1 and w[1].startswith("binary")
        elif w[:1] == ["property"] and sizes:
            elem = list(sizes)[-1]
            try:
                if w[1] == "list":  # count + at least three indices
                    sizes[elem] += (np.dtype(_PLY_TYPES[w[2]]).itemsize
                                    + 3 * np.dtype(_PLY_TYPES[w[3]]).itemsize)
                else:
                    sizes[elem] += np.dtype(_PLY_TYPES[w[1]]).itemsize
            except (KeyError, IndexError):
                raise InputError(f"unknown PLY property type in {line.strip()!r}",
                                 path=path) from None
    if binary:
        body = head.index(b"\n", end) + 1
        need = body + sum(counts[k] * sizes[k] for k in counts)
        have = path.stat().st_size
        if have < need:
            declared = ", ".join(f"{n} {k}" for k, n in counts.items())
            raise InputError(f"truncated file: its header declares {declared} elements, which "
                             f"need at least {need} bytes; the file has {have}", path=path)
    return counts


def _check_complete(path: Path, what: str, n_read: int) -> None:
    """InputError when a PLY declares more ``what`` (vertex/face) than were read."""
    declared = _ply_header_counts(path).get(what)
    if declared is not None and n_read < declared:
        raise InputError(f"truncated file: its header declares {declared} {what} elements, "
                         f"{n_read} could be read", path=path)


def _because(said: list[str]) -> str:
    """`` (RPly: Wrong magic number...)`` from what a C library said, or nothing."""
    import re

    lines = list(dict.fromkeys(re.sub(r"\x1b\[[0-9;]*m", "", ln) for ln in said))
    return f" ({'; '.join(lines[:2])})" if lines else ""


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
    said: list[str] = []
    with native_output(said):
        mesh = None
        if suffix in MESH_SUFFIXES:
            mesh = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False,
                                             print_progress=False)
        if mesh is None or (len(mesh.triangles) == 0 and suffix == ".ply"):
            pcd = o3d.io.read_point_cloud(str(path))  # a PLY of vertices only
    if mesh is not None and len(mesh.triangles) > 0:
        _check_complete(path, "vertex", len(mesh.vertices))
        _check_complete(path, "face", len(mesh.triangles))
        return mesh
    if mesh is not None and suffix != ".ply":
        if len(mesh.vertices) == 0:
            raise InputError(f"no vertices read (empty or corrupt mesh file){_because(said)}",
                             path=path)
        pcd = o3d.geometry.PointCloud(mesh.vertices)
        if mesh.has_vertex_normals():
            pcd.normals = mesh.vertex_normals
        return pcd
    if len(pcd.points) == 0:
        raise InputError(f"no points read (empty or corrupt file){_because(said)}", path=path)
    _check_complete(path, "vertex", len(pcd.points))
    return pcd
