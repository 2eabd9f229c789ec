"""Time-series output for ParaView and others: per-frame VTP files and a ``.pvd`` index,
PLY point sequences, per-step CSV tables. Shared by particles, cloth and boids.
"""

from __future__ import annotations

import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from core.files import atomic_file
from core.validate import check_array

__all__ = ["SeriesWriter", "write_vtp", "write_pvd"]


def write_vtp(path: str | os.PathLike, points: np.ndarray, *, point_data: dict | None = None,
              lines: np.ndarray | None = None, triangles: np.ndarray | None = None) -> Path:
    """Write one frame as VTK PolyData (binary XML ``.vtp``).

    Parameters
    ----------
    points : (n, 3) float64
    point_data : dict of name -> (n,) or (n, k) arrays (ids, velocity, heading, age, ...)
    lines : (m, 2) int, optional
        Segments (springs, trails).
    triangles : (m, 3) int, optional
        Faces (cloth).
    """
    import pyvista as pv

    pts = check_array(points, "points", shape=(None, 3))
    pd = pv.PolyData(pts.copy())
    if len(pts):
        pd.verts = np.hstack([np.ones((len(pts), 1), np.int64),
                              np.arange(len(pts))[:, None]]).ravel()
    if lines is not None and len(lines):
        ln = np.asarray(lines, np.int64)
        pd.lines = np.hstack([np.full((len(ln), 1), 2, np.int64), ln]).ravel()
    if triangles is not None and len(triangles):
        tr = np.asarray(triangles, np.int64)
        pd.faces = np.hstack([np.full((len(tr), 1), 3, np.int64), tr]).ravel()
    for name, arr in (point_data or {}).items():
        arr = np.asarray(arr)
        if arr.shape[:1] != (len(pts),):
            raise ValueError(f"point_data[{name!r}]: expected {len(pts)} rows, got {arr.shape}")
        if len(pts):  # VTK/pyvista reject empty arrays; an empty frame is just no points
            pd.point_data[name] = arr
    with atomic_file(path) as tmp:
        pd.save(str(tmp), binary=True)
    return Path(path)


def write_pvd(path: str | os.PathLike, entries: list[tuple[float, str]]) -> Path:
    """Write a ParaView collection: ``entries`` are ``(time, relative_file)`` pairs."""
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    for t, name in entries:
        lines.append(f'    <DataSet timestep="{float(t):.9g}" group="" part="0" '
                     f"file={quoteattr(str(name))}/>")
    lines += ["  </Collection>", "</VTKFile>", ""]
    with atomic_file(path) as tmp:
        tmp.write_text("\n".join(lines))
    return Path(path)


class SeriesWriter:
    """Writes ``frames/frame_00000.vtp ...`` under ``out_dir`` and ``series.pvd`` at close.

    >>> import tempfile, numpy as np
    >>> w = SeriesWriter(tempfile.mkdtemp())
    >>> w.add(0.0, np.zeros((2, 3)), point_data={"id": np.arange(2)})
    >>> w.close().name
    'series.pvd'
    """

    def __init__(self, out_dir: str | os.PathLike, *, prefix: str = "frame"):
        self.out_dir = Path(out_dir)
        (self.out_dir / "frames").mkdir(parents=True, exist_ok=True)
        self.prefix = prefix
        self.entries: list[tuple[float, str]] = []

    def add(self, time: float, points: np.ndarray, **kwargs) -> None:
        name = f"frames/{self.prefix}_{len(self.entries):05d}.vtp"
        write_vtp(self.out_dir / name, points, **kwargs)
        self.entries.append((time, name))

    def close(self) -> Path:
        return write_pvd(self.out_dir / "series.pvd", self.entries)
