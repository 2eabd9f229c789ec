"""ASTM E57 files (through pye57): every scan of a file, with its pose and, for
structured scans, its row and column grid.

An E57 file holds any number of scans (``/data3D``); each has points in its own frame
(cartesian, or spherical range/azimuth/elevation, converted here), an optional pose
(a unit quaternion ``w x y z`` and a translation: ``X_model = R X_scan + t``, read here as
``model_from_scan``), optional ``intensity`` and, for a structured (gridded) scan,
``rowIndex`` and ``columnIndex`` per point. Points flagged invalid
(``cartesianInvalidState`` or ``sphericalInvalidState`` not 0) are dropped.

The writer stores coordinates as 32-bit floats (pye57 writes single precision): about
1e-7 of the largest coordinate, 8 micrometres at 100 m from the scanner.

>>> import tempfile, pathlib
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> s = E57Scan("station 1", np.array([[1.0, 2, 3], [4, 5, 6]]), np.eye(4),
...             row=np.array([0, 0]), column=np.array([0, 1]))
>>> back = read_e57(write_e57(d / "a.e57", [s]))
>>> back[0].name, back[0].grid().tolist()
('station 1', [[0, 1]])
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError, check_array

__all__ = ["E57Scan", "read_e57", "write_e57"]


@dataclasses.dataclass
class E57Scan:
    """One scan of an E57 file.

    Attributes
    ----------
    name : str
    points : (n, 3) float64
        In the scan's own frame (metres).
    model_from_scan : (4, 4) float64
        The scan's pose (identity when the file gives none).
    row, column : (n,) int64 or None
        Grid position of each point in a structured scan.
    intensity : (n,) float64 or None
    """

    name: str
    points: np.ndarray
    model_from_scan: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(4))
    row: np.ndarray | None = None
    column: np.ndarray | None = None
    intensity: np.ndarray | None = None

    def grid(self) -> np.ndarray | None:
        """``index (rows, cols) int64``: the point index of each grid cell (-1 empty),
        rows and columns counted from the smallest present; None for an unstructured
        scan. When several points share a cell (multiple returns) the first is kept."""
        if self.row is None or self.column is None or not len(self.points):
            return None
        r = np.asarray(self.row, np.int64) - int(np.min(self.row))
        c = np.asarray(self.column, np.int64) - int(np.min(self.column))
        index = np.full((int(r.max()) + 1, int(c.max()) + 1), -1, np.int64)
        order = np.arange(len(r))[::-1]     # the first point of a cell written last wins
        index[r[order], c[order]] = order
        return index


def _value(node, *names, default=None):
    """The value of ``node[names[0]][names[1]]...`` or ``default`` when undefined."""
    from pye57 import libe57
    from pye57.utils import get_node

    try:
        for name in names:
            if not node.isDefined(name):
                return default
            node = get_node(node, name)
        return node.value()
    except (libe57.E57Exception, AttributeError, TypeError):
        return default


def _pose(node) -> np.ndarray:
    from pye57.utils import get_node

    from core.io.range import _quat_matrix

    T = np.eye(4)
    if not node.isDefined("pose"):
        return T
    pose = get_node(node, "pose")
    q = [_value(pose, "rotation", k, default=d) for k, d in
         (("x", 0.0), ("y", 0.0), ("z", 0.0), ("w", 1.0))]
    T[:3, :3] = _quat_matrix(q)
    T[:3, 3] = [_value(pose, "translation", k, default=0.0) for k in "xyz"]
    return T


def _scan_points(path: Path, data: dict, field: str) -> tuple[np.ndarray, np.ndarray]:
    """``(points (n, 3), valid (n,) bool)`` of one scan's raw fields."""
    from pye57.utils import convert_spherical_to_cartesian

    if all(f"cartesian{a}" in data for a in "XYZ"):
        pts = np.stack([data[f"cartesian{a}"] for a in "XYZ"], -1).astype(np.float64)
        state = data.get("cartesianInvalidState")
    elif all(k in data for k in ("sphericalRange", "sphericalAzimuth", "sphericalElevation")):
        rae = np.stack([data["sphericalRange"], data["sphericalAzimuth"],
                        data["sphericalElevation"]], -1).astype(np.float64)
        pts = convert_spherical_to_cartesian(rae)
        state = data.get("sphericalInvalidState")
    else:
        raise InputError("no cartesian or spherical coordinates", path=path, field=field)
    valid = np.ones(len(pts), bool) if state is None else np.asarray(state) == 0
    return pts, valid & np.isfinite(pts).all(axis=1)


def read_e57(path: str | os.PathLike) -> list[E57Scan]:
    """Read every scan of an E57 file, with its pose (and grid when structured).

    Raises
    ------
    InputError
        Naming the file and field: not an E57 file, no scans (``data3D``), a scan with no
        valid points (``data3D[i] (NAME)``).
    """
    import pye57
    from pye57 import libe57

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        e57 = pye57.E57(str(path), mode="r")
    except Exception as exc:  # libe57 raises its own types for a corrupt file
        raise InputError(f"not a readable E57 file ({str(exc).splitlines()[0][:120]})",
                         path=path) from None
    scans = []
    try:
        if e57.scan_count == 0:
            raise InputError("the file holds no scans", path=path, field="data3D")
        for i in range(e57.scan_count):
            node = e57.data3d[i]
            name = _value(node, "name", default=f"scan {i}")
            field = f"data3D[{i}] ({name})"
            try:
                data = e57.read_scan_raw(i, ignore_unsupported_fields=True)
            except (libe57.E57Exception, ValueError) as exc:
                raise InputError(f"unreadable points ({exc})", path=path, field=field) from None
            pts, valid = _scan_points(path, data, field)
            if not valid.any():
                raise InputError("the scan has no points", path=path, field=field)
            structured = "rowIndex" in data and "columnIndex" in data
            scans.append(E57Scan(
                name=str(name), points=pts[valid], model_from_scan=_pose(node),
                row=data["rowIndex"][valid].astype(np.int64) if structured else None,
                column=data["columnIndex"][valid].astype(np.int64) if structured else None,
                intensity=(data["intensity"][valid].astype(np.float64)
                           if "intensity" in data else None)))
    finally:
        e57.close()
    return scans


def write_e57(path: str | os.PathLike, scans: Sequence[E57Scan]) -> Path:
    """Write ``scans`` (each with its pose, grid and intensity) to one E57 file, atomically.

    Coordinates are stored as 32-bit floats (see the module's docstring); ``row`` and
    ``column`` must lie in [0, 65535].
    """
    import pye57

    from core.io.range import _matrix_quat

    path = Path(path)
    if path.suffix.lower() != ".e57":
        raise ValueError(f"path: expected a .e57 file, got {path.suffix!r}")
    if not len(scans):
        raise ValueError("scans: expected at least one scan, got none")
    records = [_record(i, s) for i, s in enumerate(scans)]
    with atomic_file(path) as tmp:
        tmp.unlink()  # libe57 creates the file itself
        e57 = pye57.E57(str(tmp), mode="w")
        try:
            for s, data in zip(scans, records, strict=True):
                T = check_array(s.model_from_scan, f"model_from_scan of {s.name}", shape=(4, 4))
                x, y, z, w = _matrix_quat(T[:3, :3])
                e57.write_scan_raw(data, name=str(s.name), rotation=np.array([w, x, y, z]),
                                   translation=T[:3, 3].copy())
        finally:
            e57.close()
    return path


def _record(i: int, s: E57Scan) -> dict:
    pts = check_array(s.points, f"scans[{i}].points", shape=(None, 3))
    if not len(pts):
        raise ValueError(f"scans[{i}].points: expected at least one point, got none")
    data = {f"cartesian{a}": np.ascontiguousarray(pts[:, k]) for k, a in enumerate("XYZ")}
    if s.intensity is not None:
        data["intensity"] = check_array(s.intensity, f"scans[{i}].intensity",
                                        shape=(len(pts),)).astype(np.float32)
    if (s.row is None) != (s.column is None):
        raise ValueError(f"scans[{i}]: row and column come together (one is None)")
    if s.row is not None:
        for key, v in (("rowIndex", s.row), ("columnIndex", s.column)):
            arr = check_array(v, f"scans[{i}].{key}", shape=(len(pts),), dtype=np.int64)
            if arr.min() < 0 or arr.max() > 65535:
                raise ValueError(f"scans[{i}].{key}: expected values in [0, 65535]")
            data[key] = arr.astype(np.uint16)
    return data
