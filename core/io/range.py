"""Range scans as scanners write them, and the poses that place them: the file formats.

- **PLY range images** (:func:`read_range_grid`, :func:`write_range_grid`): the format of
  the Stanford 3D Scanning Repository's Cyberware scans. The header gives the grid as
  ``obj_info num_cols C`` and ``obj_info num_rows R``; ``element vertex`` holds the
  measured points (``x y z``, optionally ``intensity`` and ``confidence``) in the
  scanner's own frame, and ``element range_grid`` holds ``R * C`` lists
  (``property list uchar int vertex_indices``), one per grid cell, row by row, each with
  0 (unmeasured) or 1 vertex index. ASCII and binary (either byte order) are read; the
  writer writes binary little-endian (or ASCII with ``ascii=True``).
- **scanalyze ``.conf``** (:func:`read_conf`, :func:`write_conf`): one line per scan,
  ``bmesh FILE tx ty tz qx qy qz qw`` (``mesh`` lines too; ``camera`` lines are skipped).
  The convention, checked on the Stanford dragon (``tests/test_range_io.py`` holds an
  excerpt and a test that fails under every other reading)::

      X_model = R(-qx, -qy, -qz, qw) @ X_scan + t

  i.e. ``model_from_scan = [[R(q).T, t], [0, 1]]`` where ``R(q)`` is the rotation of the
  unit quaternion ``(qx, qy, qz, qw)``: scanalyze stores the rotation of the inverse
  (model-to-scan) but the translation of the forward transform. With it the 15 posed
  dragon scans overlap their neighbours with a median gap of 0.3-0.4 mm; reading ``q``
  as is, or the line as ``scan_from_model``, leaves gaps of millimetres.
- **MeshLab ``.aln``** (:func:`read_aln`, :func:`write_aln`): the count of meshes, then
  per mesh its file name, a ``#`` line and the 4 x 4 matrix that MeshLab applies to it
  (``model_from_scan``), row by row.
- **scanamp ``poses.json``** (:func:`read_poses_json`, :func:`write_poses_json`):
  ``{"scans": [{"file", "registered", "reason", "model_from_scan": 4x4, "rms",
  "overlap"}]}``, one entry per scan (:class:`ScanPose`).

Poses are ``model_from_scan`` (4, 4) float64: scan coordinates to model coordinates.
Every reader raises :class:`core.validate.InputError` naming the file and the field;
every writer is atomic.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> pts = np.array([[0.0, 0, 1], [0.1, 0, 1], [0.0, 0.1, 1]])
>>> grid = RangeGrid(pts, np.array([[0, 1], [2, -1]]))
>>> back = read_range_grid(write_range_grid(d / "s.ply", grid))
>>> back.index.tolist(), bool(np.array_equal(back.points, pts))
([[0, 1], [2, -1]], True)
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from core.files import atomic_file, read_json, read_text, write_json
from core.validate import InputError, check_array

__all__ = ["RangeGrid", "read_range_grid", "write_range_grid", "is_range_grid",
           "read_conf", "write_conf", "conf_files", "read_aln", "write_aln",
           "ScanPose", "read_poses_json", "write_poses_json",
           "model_from_conf", "conf_from_model"]

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


# ---------------------------------------------------------------------------------------
# PLY range images
# ---------------------------------------------------------------------------------------

@dataclasses.dataclass
class RangeGrid:
    """A range image: measured points and the grid cell each came from.

    Attributes
    ----------
    points : (n, 3) float64
        Measured points in the scanner's frame (metres).
    index : (rows, cols) int64
        Vertex index of each grid cell, -1 where nothing was measured. Row ``r``,
        column ``c`` is the file's cell ``r * cols + c``; neighbouring cells are
        neighbouring samples.
    intensity : (n,) float64 or None
        Per-point intensity (reflectance) when the file has it.
    path : Path or None
        The file it was read from.
    confidence : (n,) float64 or None
        Per-point confidence when the file has it (Stanford's later scans do).
    obj_info : dict
        The header's other ``obj_info`` lines (name -> text), kept for the writer.
    """

    points: np.ndarray
    index: np.ndarray
    intensity: np.ndarray | None = None
    path: Path | None = None
    confidence: np.ndarray | None = None
    obj_info: dict = dataclasses.field(default_factory=dict)

    @property
    def rows(self) -> int:
        return int(self.index.shape[0])

    @property
    def cols(self) -> int:
        return int(self.index.shape[1])


def _parse_header(path: Path, data: bytes):
    """``(format, elements, obj_info, body_start)`` of a PLY; elements are
    ``[name, count, [[type, name] or ["list", ctype, itype, name], ...]]``."""
    if not data.startswith(b"ply"):
        raise InputError("not a PLY file (no 'ply' magic)", path=path)
    end = data.find(b"end_header")
    if end < 0:
        raise InputError("truncated or corrupt PLY: its header has no end_header", path=path)
    nl = data.find(b"\n", end)
    body_start = len(data) if nl < 0 else nl + 1
    fmt, elements, obj_info = None, [], {}
    for line in data[:end].decode("ascii", "replace").splitlines():
        w = line.split()
        if not w:
            continue
        if w[0] == "format" and len(w) > 1:
            fmt = w[1]
        elif w[0] == "obj_info" and len(w) > 1:
            obj_info[w[1]] = " ".join(w[2:])
        elif w[0] == "element":
            if len(w) != 3 or not w[2].isdigit():
                raise InputError(f"malformed header line {line.strip()!r}", path=path,
                                 field="element")
            elements.append([w[1], int(w[2]), []])
        elif w[0] == "property" and elements:
            types = w[2:4] if w[1:2] == ["list"] else w[1:2]
            if len(w) < (5 if w[1:2] == ["list"] else 3) or any(t not in _PLY_TYPES
                                                                  for t in types):
                raise InputError(f"unknown PLY property in {line.strip()!r}", path=path,
                                 field=f"element {elements[-1][0]}")
            elements[-1][2].append(w[1:])
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"{fmt!r} is not a PLY format (ascii, binary_little_endian, "
                         "binary_big_endian)", path=path, field="format")
    return fmt, elements, obj_info, body_start


def is_range_grid(path: str | os.PathLike) -> bool:
    """True when ``path`` is a PLY whose header declares a ``range_grid`` element."""
    path = Path(path)
    if path.suffix.lower() != ".ply" or not path.is_file():
        return False
    with open(path, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    return head.startswith(b"ply") and end > 0 and any(
        ln.split()[:2] == [b"element", b"range_grid"] for ln in head[:end].splitlines())


def _grid_shape(path: Path, obj_info: dict) -> tuple[int, int]:
    shape = []
    for key in ("num_rows", "num_cols"):
        text = obj_info.get(key)
        if text is None:
            raise InputError("missing: a range image gives its grid as 'obj_info num_cols C' "
                             "and 'obj_info num_rows R'", path=path, field=f"obj_info {key}")
        try:
            value = int(text)
        except ValueError:
            value = -1
        if value < 1:
            raise InputError(f"expected a positive integer, got {text!r}", path=path,
                             field=f"obj_info {key}")
        shape.append(value)
    return shape[0], shape[1]


def read_range_grid(path: str | os.PathLike) -> RangeGrid:
    """Read a PLY range image (ASCII or binary) with its grid.

    Returns
    -------
    RangeGrid
        ``points (n, 3) float64`` and ``index (rows, cols) int64`` (-1 empty).

    Raises
    ------
    InputError
        Naming the file and field: not a PLY, no ``range_grid`` element, no
        ``obj_info num_cols``/``num_rows``, a grid size that disagrees with the number of
        cells (``range_grid``), a cell with more than one index or one out of range,
        no points (``vertex``), a truncated body.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    data = path.read_bytes()
    fmt, elements, obj_info, body = _parse_header(path, data)
    names = [e[0] for e in elements]
    if "range_grid" not in names:
        raise InputError("no range_grid element: not a range image (read it as a point "
                         "cloud or mesh instead)", path=path, field="range_grid")
    if "vertex" not in names:
        raise InputError("no vertex element", path=path, field="vertex")
    rows, cols = _grid_shape(path, obj_info)
    n_cells = dict((e[0], e[1]) for e in elements)["range_grid"]
    if n_cells != rows * cols:
        raise InputError(f"{n_cells} cells, but the grid is num_rows {rows} x num_cols {cols}"
                         f" = {rows * cols}", path=path, field="range_grid")
    try:
        if fmt == "ascii":
            parsed = _read_ascii(path, data[body:], elements)
        else:
            parsed = _read_binary(path, data, body, elements,
                                  "<" if fmt == "binary_little_endian" else ">")
    except InputError:
        raise
    except (ValueError, IndexError) as exc:
        raise InputError(f"truncated or malformed PLY body ({exc})", path=path) from None
    vertex, cells = parsed["vertex"], parsed["range_grid"]
    props = vertex.dtype.names or ()
    if not all(c in props for c in "xyz"):
        raise InputError("expected properties x, y, z", path=path, field="vertex")
    points = np.stack([vertex["x"], vertex["y"], vertex["z"]], -1).astype(np.float64)
    if not len(points):
        raise InputError("no points: the scan measured nothing", path=path, field="vertex")
    bad = int(np.count_nonzero(~np.isfinite(points).all(axis=1)))
    if bad:
        raise InputError(f"{bad} points with NaN or infinite coordinates", path=path,
                         field="vertex")
    out_of_range = (cells < -1) | (cells >= len(points))
    if np.any(out_of_range):
        k = int(np.flatnonzero(out_of_range)[0])
        raise InputError(f"cell {k} (row {k // cols}, column {k % cols}) holds vertex index "
                         f"{int(cells[k])}, outside [0, {len(points)})", path=path,
                         field="range_grid")
    extra = {k: vertex[k].astype(np.float64) for k in ("intensity", "confidence") if k in props}
    info = {k: v for k, v in obj_info.items() if k not in ("num_cols", "num_rows")}
    return RangeGrid(points, cells.reshape(rows, cols), intensity=extra.get("intensity"),
                     path=path, confidence=extra.get("confidence"), obj_info=info)


def _cells_from_lists(path: Path, counts: np.ndarray, first: np.ndarray) -> np.ndarray:
    """Cell -> vertex index (-1 empty) from each cell's list length and first entry."""
    many = np.flatnonzero(counts > 1)
    if len(many):
        k = int(many[0])
        raise InputError(f"cell {k} lists {int(counts[k])} vertex indices, expected 0 or 1",
                         path=path, field="range_grid")
    return np.where(counts == 1, first, -1).astype(np.int64)


def _read_ascii(path: Path, body: bytes, elements) -> dict:
    newlines = np.flatnonzero(np.frombuffer(body, np.uint8) == 10)
    out, row = {}, 0
    for name, count, props in elements:
        if row + count > len(newlines) + 1:
            raise ValueError(f"element {name}: expected {count} lines, the body ends first")
        start = 0 if row == 0 else int(newlines[row - 1]) + 1
        end = int(newlines[row + count - 1]) if row + count - 1 < len(newlines) else len(body)
        block = body[start:end].decode("ascii") if count else ""
        row += count
        if name == "range_grid":
            out[name] = _ascii_cells(path, block, count)
        elif name == "vertex":
            if any(p[0] == "list" for p in props):
                raise ValueError("list properties of vertices are not supported")
            vals = np.array(block.split(), np.float64)
            if vals.size != count * len(props):
                raise ValueError(f"vertex: expected {count * len(props)} numbers, "
                                 f"found {vals.size}")
            arr = vals.reshape(count, len(props))
            rec = np.empty(count, [(p[1], np.float64) for p in props])
            for i, p in enumerate(props):
                rec[p[1]] = arr[:, i]
            out[name] = rec
    return out


def _ascii_cells(path: Path, block: str, count: int) -> np.ndarray:
    """Cells of an ASCII ``range_grid`` block: each line a count and that many indices."""
    tokens = np.array(block.split(), np.int64).tolist()
    counts, first = [0] * count, [-1] * count
    pos = 0
    for k in range(count):
        c = tokens[pos]
        counts[k] = c
        if c > 0:
            first[k] = tokens[pos + 1]
        pos += 1 + max(c, 0)
    if pos != len(tokens) or min(counts, default=0) < 0:
        raise ValueError("range_grid: the lines' lengths disagree with their counts")
    return _cells_from_lists(path, np.array(counts, np.int64), np.array(first, np.int64))


def _read_binary(path: Path, data: bytes, pos: int, elements, order: str) -> dict:
    out = {}
    for name, count, props in elements:
        if not any(p[0] == "list" for p in props):
            dt = np.dtype([(p[1], order + _PLY_TYPES[p[0]]) for p in props])
            rec = np.frombuffer(data, dt, count, pos)
            pos += dt.itemsize * count
            out[name] = rec
            continue
        counts, first, pos = _walk_lists(data, pos, count, props, order)
        if name == "range_grid":
            out[name] = _cells_from_lists(path, counts, first)
    return out


def _walk_lists(data: bytes, pos: int, count: int, props, order: str):
    """Walk ``count`` binary records with list properties; for the first list, each
    record's length and first entry. Returns ``(counts, first, end_pos)``."""
    counts = np.zeros(count, np.int64)
    first = np.full(count, -1, np.int64)
    layout = []
    for p in props:
        if p[0] == "list":
            layout.append((np.dtype(order + _PLY_TYPES[p[1]]), np.dtype(order + _PLY_TYPES[p[2]])))
        else:
            layout.append((None, np.dtype(order + _PLY_TYPES[p[0]])))
    # the common case (a range grid): one list of uchar count and int entries
    if len(layout) == 1 and layout[0][0] is not None and layout[0][0].itemsize == 1:
        isz, idt = layout[0][1].itemsize, layout[0][1]
        for k in range(count):
            c = data[pos]
            counts[k] = c
            if c:
                first[k] = int(np.frombuffer(data, idt, 1, pos + 1)[0])
            pos += 1 + c * isz
        if pos > len(data):
            raise ValueError("the body ends before its last range_grid cell")
        return counts, first, pos
    seen_list = False
    for k in range(count):
        for cdt, vdt in layout:
            if cdt is None:
                pos += vdt.itemsize
                continue
            c = int(np.frombuffer(data, cdt, 1, pos)[0])
            if not seen_list:
                counts[k] = c
                if c:
                    first[k] = int(np.frombuffer(data, vdt, 1, pos + cdt.itemsize)[0])
            pos += cdt.itemsize + c * vdt.itemsize
        seen_list = False
    if pos > len(data):
        raise ValueError("the body ends before its last record")
    return counts, first, pos


def _check_grid(grid: RangeGrid) -> tuple[np.ndarray, np.ndarray]:
    points = check_array(grid.points, "grid.points", shape=(None, 3))
    index = check_array(grid.index, "grid.index", shape=(None, None), dtype=np.int64)
    if index.size == 0:
        raise ValueError(f"grid.index: expected at least one row and column, got {index.shape}")
    if np.any((index < -1) | (index >= len(points))):
        raise ValueError(f"grid.index: expected -1 or a vertex index in [0, {len(points)})")
    for name in ("intensity", "confidence"):
        value = getattr(grid, name)
        if value is not None:
            check_array(value, f"grid.{name}", shape=(len(points),))
    return points, index


def write_range_grid(path: str | os.PathLike, grid: RangeGrid, *, ascii: bool = False) -> Path:
    """Write ``grid`` as a PLY range image (binary little-endian, or ASCII), atomically.

    Vertices are ``double x y z`` (plus ``float intensity``/``confidence`` when present);
    ``obj_info num_cols``/``num_rows`` and the grid's other ``obj_info`` lines go in the
    header; ``range_grid`` is one ``uchar int`` list per cell, row by row.
    """
    path = Path(path)
    points, index = _check_grid(grid)
    rows, cols = index.shape
    extras = [(k, np.asarray(getattr(grid, k), np.float64))
              for k in ("intensity", "confidence") if getattr(grid, k) is not None]
    info = {k: v for k, v in grid.obj_info.items() if k not in ("num_cols", "num_rows")}
    header = ["ply", "format " + ("ascii 1.0" if ascii else "binary_little_endian 1.0"),
              "comment range image written by scanamp",
              *(f"obj_info {k} {v}".rstrip() for k, v in info.items()),
              f"obj_info num_cols {cols}", f"obj_info num_rows {rows}",
              f"element vertex {len(points)}", "property double x", "property double y",
              "property double z", *(f"property float {k}" for k, _ in extras),
              f"element range_grid {rows * cols}", "property list uchar int vertex_indices",
              "end_header"]
    flat = index.reshape(-1)
    with atomic_file(path) as tmp, open(tmp, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        if ascii:
            cols_v = [points] + [v[:, None] for _, v in extras]
            np.savetxt(fh, np.hstack(cols_v), fmt=["%.17g"] * 3 + ["%.9g"] * len(extras))
            fh.write("".join("0\n" if i < 0 else f"1 {i}\n" for i in flat.tolist())
                     .encode("ascii"))
        else:
            vdt = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
                           + [(k, "<f4") for k, _ in extras])
            rec = np.empty(len(points), vdt)
            rec["x"], rec["y"], rec["z"] = points.T
            for k, v in extras:
                rec[k] = v
            fh.write(rec.tobytes())
            fh.write(_grid_bytes(flat))
    return path


def _grid_bytes(flat: np.ndarray) -> bytes:
    """The binary ``range_grid`` body: per cell a uchar count, then the int32 index."""
    valid = flat >= 0
    sizes = np.where(valid, 5, 1)
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    buf = np.zeros(int(sizes.sum()), np.uint8)
    buf[offsets] = valid
    idx = flat[valid].astype("<i4").view(np.uint8).reshape(-1, 4)
    for k in range(4):
        buf[offsets[valid] + 1 + k] = idx[:, k]
    return buf.tobytes()


# ---------------------------------------------------------------------------------------
# Poses
# ---------------------------------------------------------------------------------------

def _quat_matrix(q) -> np.ndarray:
    """Rotation (3, 3) of the quaternion ``(x, y, z, w)`` (normalised first)."""
    x, y, z, w = np.asarray(q, np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _matrix_quat(R) -> np.ndarray:
    """The unit quaternion ``(x, y, z, w)`` (``w >= 0``) of a rotation (3, 3)."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(np.asarray(R, np.float64)).as_quat()
    return -q if q[3] < 0 else q


def model_from_conf(t, q) -> np.ndarray:
    """``model_from_scan`` (4, 4) of a scanalyze pose: translation ``t`` and quaternion
    ``q = (qx, qy, qz, qw)`` as the ``.conf`` line gives them (the module's docstring has
    the convention: ``R(-qx, -qy, -qz, qw)``, i.e. ``R(q).T``, then ``+ t``).

    >>> T = model_from_conf([0.1, 0, 0], [0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    >>> np.round(T @ [1.0, 0, 0, 1], 12)[:3] + 0.0
    array([ 0.1, -1. ,  0. ])
    """
    T = np.eye(4)
    T[:3, :3] = _quat_matrix(q).T
    T[:3, 3] = np.asarray(t, np.float64)
    return T


def conf_from_model(model_from_scan) -> tuple[np.ndarray, np.ndarray]:
    """The ``.conf`` translation and quaternion ``(qx, qy, qz, qw)`` of a pose (the inverse
    of :func:`model_from_conf`)."""
    T = check_array(model_from_scan, "model_from_scan", shape=(4, 4))
    return T[:3, 3].copy(), _matrix_quat(T[:3, :3].T)


def _numbers(path: Path, field: str, words: Sequence[str], n: int) -> list[float]:
    if len(words) != n:
        raise InputError(f"expected {n} numbers, got {len(words)}", path=path, field=field)
    try:
        vals = [float(w) for w in words]
    except ValueError:
        raise InputError(f"expected numbers, got {' '.join(words)!r}", path=path,
                         field=field) from None
    if not all(math.isfinite(v) for v in vals):
        raise InputError("expected finite numbers", path=path, field=field)
    return vals


def read_conf(path: str | os.PathLike) -> list[tuple[str, np.ndarray]]:
    """Read a scanalyze ``.conf``: ``[(file, model_from_scan (4, 4)), ...]``.

    ``bmesh`` and ``mesh`` lines are scans (file names as written, relative to the
    ``.conf``'s folder); ``camera`` lines and blank or ``#`` lines are skipped. Whether the
    files exist is :func:`conf_files`'s question.
    """
    path = Path(path)
    out = []
    for k, line in enumerate(read_text(path).splitlines(), 1):
        w = line.split()
        if not w or w[0].startswith("#") or w[0] == "camera":
            continue
        field = f"line {k}"
        if w[0] not in ("bmesh", "mesh"):
            raise InputError(f"expected 'bmesh FILE tx ty tz qx qy qz qw', got {line.strip()!r}",
                             path=path, field=field)
        if len(w) < 2:
            raise InputError("missing the file name", path=path, field=field)
        vals = _numbers(path, f"{field} ({w[1]})", w[2:], 7)
        if np.linalg.norm(vals[3:]) < 1e-12:
            raise InputError("the quaternion is zero", path=path, field=f"{field} ({w[1]})")
        out.append((w[1], model_from_conf(vals[:3], vals[3:])))
    if not out:
        raise InputError("no 'bmesh' or 'mesh' line: no scan named", path=path)
    return out


def conf_files(path: str | os.PathLike, entries=None) -> list[tuple[Path, np.ndarray]]:
    """The scans a ``.conf`` names, resolved beside it: ``[(Path, model_from_scan)]``.

    A name without a suffix is tried with ``.ply``. A file that exists under neither
    name raises InputError naming the ``.conf`` and the line's file.
    """
    path = Path(path)
    entries = read_conf(path) if entries is None else entries
    out = []
    for name, T in entries:
        f = path.parent / name
        if not f.is_file() and not f.suffix:
            f = f.with_name(f.name + ".ply")
        if not f.is_file():
            raise InputError(f"names {name!r}, which is not a file beside it", path=path,
                             field=f"bmesh {name}")
        out.append((f, T))
    return out


def write_conf(path: str | os.PathLike, entries: Sequence[tuple[str, np.ndarray]]) -> Path:
    """Write ``[(file, model_from_scan), ...]`` as scanalyze ``bmesh`` lines, atomically."""
    lines = []
    for name, T in entries:
        t, q = conf_from_model(T)
        lines.append("bmesh " + " ".join([str(name), *(f"{v:.17g}" for v in (*t, *q))]))
    with atomic_file(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return Path(path)


def read_aln(path: str | os.PathLike) -> list[tuple[str, np.ndarray]]:
    """Read a MeshLab ``.aln``: ``[(file, model_from_scan (4, 4)), ...]``."""
    path = Path(path)
    lines = [ln.strip() for ln in read_text(path).splitlines()]
    lines = [ln for ln in lines if ln]
    try:
        n = int(lines[0])
    except (IndexError, ValueError):
        raise InputError("expected the number of meshes on the first line", path=path,
                         field="line 1") from None
    out, pos = [], 1
    for i in range(n):
        if pos >= len(lines):
            raise InputError(f"declares {n} meshes, found {i}", path=path, field="meshes")
        name = lines[pos]
        pos += 1
        while pos < len(lines) and lines[pos].startswith("#"):
            pos += 1
        rows = [_numbers(path, f"{name} matrix row {r + 1}",
                         lines[pos + r].split() if pos + r < len(lines) else [], 4)
                for r in range(4)]
        pos += 4
        T = np.array(rows)
        if not np.allclose(T[3], [0, 0, 0, 1]):
            raise InputError(f"expected a rigid transform ending 0 0 0 1, got {rows[3]}",
                             path=path, field=f"{name} matrix row 4")
        out.append((name, T))
    return out


def write_aln(path: str | os.PathLike, entries: Sequence[tuple[str, np.ndarray]]) -> Path:
    """Write ``[(file, model_from_scan), ...]`` as a MeshLab ``.aln``, atomically."""
    parts = [str(len(entries))]
    for name, T in entries:
        T = check_array(T, f"model_from_scan of {name}", shape=(4, 4))
        parts += [str(name), "#"] + [" ".join(f"{v:.17g}" for v in row) for row in T]
    parts.append("0")
    with atomic_file(path) as tmp:
        tmp.write_text("\n".join(parts) + "\n")
    return Path(path)


@dataclasses.dataclass
class ScanPose:
    """One scan's entry of ``poses.json``.

    Attributes
    ----------
    file : str
        The scan's file (as given, or relative to the poses file's folder).
    model_from_scan : (4, 4) float64 or None
        Its placement; None when it could not be placed.
    registered : bool
    reason : str
        Why it was not registered ("" when it was).
    rms : float or None
        RMS residual (metres) of its final alignment.
    overlap : float or None
        Fraction of its points that found a partner in the other scans.
    """

    file: str
    model_from_scan: np.ndarray | None
    registered: bool = True
    reason: str = ""
    rms: float | None = None
    overlap: float | None = None


def _opt_float(value) -> float | None:
    return None if value is None or not math.isfinite(float(value)) else float(value)


def write_poses_json(path: str | os.PathLike, poses: Sequence[ScanPose]) -> Path:
    """Write ``{"scans": [...]}`` atomically (NaN written as null)."""
    scans = []
    for p in poses:
        T = None if p.model_from_scan is None else check_array(
            p.model_from_scan, f"model_from_scan of {p.file}", shape=(4, 4)).tolist()
        scans.append({"file": str(p.file), "registered": bool(p.registered),
                      "reason": str(p.reason), "model_from_scan": T,
                      "rms": _opt_float(p.rms), "overlap": _opt_float(p.overlap)})
    return write_json(path, {"scans": scans})


def read_poses_json(path: str | os.PathLike) -> list[ScanPose]:
    """Read ``poses.json``; InputError naming the file and the field (``scans[2].rms``)."""
    from core.files import require

    path = Path(path)
    data = read_json(path)
    if not isinstance(data, dict):
        raise InputError("expected an object with a 'scans' list", path=path)
    scans = require(data, "scans", list, path=path)
    out = []
    for i, s in enumerate(scans):
        pre = f"scans[{i}]"
        if not isinstance(s, dict):
            raise InputError("expected an object", path=path, field=pre)
        file = require(s, "file", str, path=path, prefix=pre)
        registered = require(s, "registered", bool, path=path, prefix=pre, default=True)
        reason = require(s, "reason", str, path=path, prefix=pre, default="")
        raw = require(s, "model_from_scan", (list, type(None)), path=path, prefix=pre,
                      default=None)
        T = None
        if raw is not None:
            try:
                T = check_array(raw, "model_from_scan", shape=(4, 4))
            except ValueError as exc:
                raise InputError(str(exc).split(": ", 1)[1], path=path,
                                 field=f"{pre}.model_from_scan") from None
        elif registered:
            raise InputError("missing for a registered scan", path=path,
                             field=f"{pre}.model_from_scan")
        vals = [require(s, k, (float, type(None)), path=path, prefix=pre, default=None)
                for k in ("rms", "overlap")]
        out.append(ScanPose(file, T, registered, reason, *vals))
    return out
