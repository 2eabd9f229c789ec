"""The range scan as registration and merging see it: points in the scanner's frame with
their normals, lines of sight, confidences and, for a range image, its triangles and grid.

A range image (:func:`scan_from_grid`) is triangulated over its grid: each 2 x 2 block of
measured cells gives two triangles (split along the shorter diagonal), or one when a cell
is empty. A triangle is dropped when one of its edges jumps more than ``max_jump`` times
the local sample spacing (the shortest edge along the same grid axis within two cells:
a depth discontinuity, two surfaces that are not one), or when it is seen more obliquely
than ``max_sight_deg`` from the scanner (a grazing sliver, or a fold seen from behind).
Vertex normals are the area-weighted triangle normals. The confidence of a vertex is, as
in VRIP (Curless and Levoy 1996), the cosine between its normal and its line of sight,
times a ramp from 0 at the scan's boundary to 1 ``edge_steps`` grid steps inside it
(times the file's own confidence when it has one). Points in no triangle keep their line
of sight as normal and confidence 0.

Lines of sight (unit vectors from each point toward the scanner) of a range image:

- a Cyberware scan (``obj_info is_cyberware_data 1``, the Stanford repository's): the
  scanner looks down its -z axis from far away, so every line of sight is +z (checked on
  the dragon: the outward normals of every scan point to +z);
- any other range image (``scanamp capture scans`` writes these): a perspective scanner at
  the frame's origin.

A plain point cloud or mesh (:func:`scan_from_points`) is seen from ``origin``; normals
are estimated (k-nearest-neighbour plane fits) and turned toward it when the file has
none.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from core.frames import transform_points, unit
from core.io.range import RangeGrid
from core.meshes import face_normals, vertex_normals
from core.validate import InputError, check_array, check_range

__all__ = ["RangeScan", "scan_from_grid", "scan_from_points", "grid_sight"]


@dataclasses.dataclass
class RangeScan:
    """One scan in its scanner's frame.

    Attributes
    ----------
    name : str
        How reports name it (the file's name, ``FILE[i]`` for the i-th scan of an E57).
    points : (n, 3) float64
        In the scanner's frame (metres).
    normals : (n, 3) float64
        Unit normals, facing the scanner.
    sight : (n, 3) float64
        Unit vectors from each point toward the scanner.
    confidence : (n,) float64
        In [0, 1]: low at grazing angles and near the scan's edges.
    triangles : (m, 3) int32
        The scan's own triangulation (empty for a point cloud).
    grid : (rows, cols) int64 or None
        Point index of each grid cell (-1 empty) for a range image.
    origin : (3,) float64
        The scanner's position in the scan frame: zeros for range images (for Cyberware
        scans, whose lines of sight are parallel, it means nothing: use ``sight``).
    path : Path or None
        The file it came from.
    model_from_scan : (4, 4) float64 or None
        A pose the file itself gave (E57), at most an initial guess; None otherwise.
    """

    name: str
    points: np.ndarray
    normals: np.ndarray
    sight: np.ndarray
    confidence: np.ndarray
    triangles: np.ndarray = dataclasses.field(
        default_factory=lambda: np.empty((0, 3), np.int32))
    grid: np.ndarray | None = None
    origin: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))
    path: Path | None = None
    model_from_scan: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.points)

    def transformed(self, model_from_scan: np.ndarray) -> RangeScan:
        """The same scan with points, normals, lines of sight and origin mapped by
        ``model_from_scan (4, 4)`` (grid, triangles and confidence unchanged)."""
        T = check_array(model_from_scan, "model_from_scan", shape=(4, 4))
        R, t = T[:3, :3], T[:3, 3]
        return dataclasses.replace(self, points=transform_points(T, self.points),
                                   normals=self.normals @ R.T, sight=self.sight @ R.T,
                                   origin=R @ self.origin + t)


def grid_sight(grid: RangeGrid) -> tuple[np.ndarray, np.ndarray]:
    """Lines of sight ``(n, 3)`` of a range image's points and the scanner's ``origin (3,)``
    (module docstring: Cyberware, or a scanner at the origin)."""
    p = grid.points
    if grid.obj_info.get("is_cyberware_data", "0").strip() == "1":
        return np.broadcast_to([0.0, 0.0, 1.0], p.shape).copy(), np.zeros(3)
    return unit(-p), np.zeros(3)


def _quads(index: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Candidate triangles ``(m, 3)`` of the grid and the ``(row, col)`` ``(m, 2)`` of the
    2 x 2 block each comes from."""
    a, b = index[:-1, :-1], index[:-1, 1:]
    c, d = index[1:, :-1], index[1:, 1:]
    va, vb, vc, vd = a >= 0, b >= 0, c >= 0, d >= 0
    full = va & vb & vc & vd
    diag_ad = np.full(a.shape, np.inf)
    diag_bc = np.full(a.shape, np.inf)
    diag_ad[full] = np.linalg.norm(p[a[full]] - p[d[full]], axis=1)
    diag_bc[full] = np.linalg.norm(p[b[full]] - p[c[full]], axis=1)
    use_ad = full & (diag_ad <= diag_bc)
    use_bc = full & ~use_ad
    # (corners, mask, which quad) ; the winding goes a -> c -> d (down, then right)
    cases = [((a, c, d), use_ad), ((a, d, b), use_ad), ((a, c, b), use_bc), ((b, c, d), use_bc),
             ((a, c, d), ~full & va & vc & vd), ((a, d, b), ~full & va & vd & vb),
             ((a, c, b), ~full & va & vc & vb), ((b, c, d), ~full & vb & vc & vd)]
    tris, quad = [], []
    for (x, y, z), m in cases:
        tris.append(np.stack([x[m], y[m], z[m]], -1))
        quad.append(np.stack(np.nonzero(m), -1))
    return np.concatenate(tris), np.concatenate(quad)


def _local_spacing(index: np.ndarray, p: np.ndarray, axis: int) -> np.ndarray:
    """Per grid edge along ``axis`` (``(rows, cols-1)`` for axis 1), the shortest measured
    edge along the same axis within two cells: the local sample spacing."""
    from scipy.ndimage import minimum_filter

    a = index[:, :-1] if axis == 1 else index[:-1, :]
    b = index[:, 1:] if axis == 1 else index[1:, :]
    ok = (a >= 0) & (b >= 0)
    length = np.full(a.shape, np.inf)
    length[ok] = np.linalg.norm(p[a[ok]] - p[b[ok]], axis=1)
    if not ok.any():
        return length
    local = minimum_filter(length, size=5, mode="nearest")
    floor = 0.25 * float(np.median(length[ok]))   # a duplicate sample is not the spacing
    return np.where(np.isfinite(local), np.maximum(local, floor), np.median(length[ok]))


def _jumps(tris: np.ndarray, quad: np.ndarray, index: np.ndarray, p: np.ndarray,
           max_jump: float) -> np.ndarray:
    """True for triangles with an edge longer than ``max_jump`` local spacings (along its
    grid axis; a diagonal against the diagonal of the two)."""
    h = _local_spacing(index, p, 1)      # (rows, cols-1)
    v = _local_spacing(index, p, 0)      # (rows-1, cols)
    r, c = quad[:, 0], quad[:, 1]
    sh = np.minimum(h[r, c], h[r + 1, c])[:, None]
    sv = np.minimum(v[r, c], v[r, c + 1])[:, None]
    axis = _edge_axis(tris, index, len(p))
    limit = max_jump * np.where(axis == 0, sh, np.where(axis == 1, sv, np.hypot(sh, sv)))
    e = np.stack([np.linalg.norm(p[tris[:, i]] - p[tris[:, (i + 1) % 3]], axis=1)
                  for i in range(3)], -1)
    return np.any(e > limit, axis=1)


def _edge_axis(tris: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    """Per triangle edge ``(m, 3)``: 0 along a row, 1 along a column, 2 diagonal."""
    rows = np.zeros(n, np.int64)
    cols = np.zeros(n, np.int64)
    r, c = np.nonzero(index >= 0)
    rows[index[r, c]], cols[index[r, c]] = r, c
    out = np.full(tris.shape, 2)
    for i in range(3):
        u, w = tris[:, i], tris[:, (i + 1) % 3]
        out[rows[u] == rows[w], i] = 0
        out[(cols[u] == cols[w]) & (rows[u] != rows[w]), i] = 1
    return out


def _edge_ramp(index: np.ndarray, used: np.ndarray, edge_steps: float) -> np.ndarray:
    """Per point: 0 on the scan's boundary (a cell next to one with no triangle, or the
    grid's edge) rising linearly to 1 ``edge_steps`` grid steps inside."""
    from scipy.ndimage import distance_transform_edt

    cell_used = np.zeros(index.shape, bool)
    valid = index >= 0
    cell_used[valid] = used[index[valid]]
    dist = distance_transform_edt(np.pad(cell_used, 1))[1:-1, 1:-1]
    ramp = np.zeros(len(used))
    ramp[index[valid]] = np.clip((dist[valid] - 1.0) / max(edge_steps, 1e-9), 0.0, 1.0)
    return ramp


def scan_from_grid(grid: RangeGrid, *, name: str | None = None, max_jump: float = 4.0,
                   max_sight_deg: float = 80.0, edge_steps: float = 3.0,
                   sight: np.ndarray | None = None) -> RangeScan:
    """Triangulate a range image into a :class:`RangeScan` (module docstring has the rules).

    Parameters
    ----------
    grid : RangeGrid
    name : str, optional
        Default: the file's name.
    max_jump : float
        Longest edge joined, in local sample spacings (a longer one is a depth jump).
    max_sight_deg : float
        Most oblique triangle kept: angle between its normal and the line of sight.
    edge_steps : float
        Grid steps over which the confidence ramps up from the scan's boundary.
    sight : (3,) or (n, 3) float64, optional
        Lines of sight (toward the scanner) instead of those the file implies.

    >>> r, c = np.mgrid[0:4, 0:5]
    >>> pts = np.stack([c.ravel() * 1e-3, r.ravel() * 1e-3, np.full(20, 0.5)], -1)
    >>> s = scan_from_grid(RangeGrid(pts, np.arange(20).reshape(4, 5)), name="plane")
    >>> len(s.triangles), bool(np.allclose(s.normals, [0, 0, -1]))
    (24, True)
    """
    p = check_array(grid.points, "grid.points", shape=(None, 3))
    index = check_array(grid.index, "grid.index", shape=(None, None), dtype=np.int64)
    check_range(max_jump, "max_jump", 1.0, None)
    check_range(max_sight_deg, "max_sight_deg", 0.0, 90.0, lo_open=True)
    check_range(edge_steps, "edge_steps", 0.0, None)
    label = name or (grid.path.name if grid.path is not None else "scan")
    if not len(p):
        raise InputError("the scan has no points", path=grid.path, field="vertex")
    s, origin = grid_sight(grid)
    if sight is not None:
        s = unit(np.broadcast_to(np.asarray(sight, np.float64), p.shape).copy())
    tris, quad = _quads(index, p)
    fn = face_normals(p, tris)
    facing = np.einsum("ij,ij->i", fn, s[tris].mean(axis=1))
    if np.sum(facing) < 0:             # the grid's winding is left-handed: turn them all
        tris, fn, facing = tris[:, ::-1], -fn, -facing
    keep = ~_jumps(tris, quad, index, p, max_jump)
    keep &= facing >= np.cos(np.radians(max_sight_deg))
    tris = tris[keep]
    used = np.zeros(len(p), bool)
    used[tris.reshape(-1)] = True
    normals = vertex_normals(p, tris)
    normals[~used] = s[~used]
    cosine = np.clip(np.einsum("ij,ij->i", normals, s), 0.0, 1.0)
    conf = np.where(used, cosine * _edge_ramp(index, used, edge_steps), 0.0)
    if grid.confidence is not None:
        conf *= np.clip(grid.confidence, 0.0, 1.0)
    return RangeScan(label, p, normals, s, conf, tris.astype(np.int32), index.copy(),
                     origin, grid.path)


def scan_from_points(points: np.ndarray, normals: np.ndarray | None = None, *,
                     name: str = "scan", origin=(0.0, 0.0, 0.0),
                     triangles: np.ndarray | None = None, neighbours: int = 16,
                     path: Path | None = None) -> RangeScan:
    """A :class:`RangeScan` of a point cloud (or mesh) seen from ``origin``.

    Parameters
    ----------
    points : (n, 3) float64
    normals : (n, 3) float64, optional
        Kept (made unit) when given; else estimated from ``neighbours`` nearest points
        (vertex normals of ``triangles`` for a mesh) and turned toward ``origin``.
    origin : (3,) float64
        The scanner's position in the points' frame.
    triangles : (m, 3) int, optional

    The confidence is the cosine between normal and line of sight (no grid: no edge ramp).

    >>> pts = np.random.default_rng(0).uniform(-0.1, 0.1, (200, 3)) * [1, 1, 0] + [0, 0, 1]
    >>> s = scan_from_points(pts, name="plane")
    >>> bool(np.all(s.normals[:, 2] < -0.99)), bool(s.confidence.min() > 0.95)
    (True, True)
    """
    p = check_array(points, "points", shape=(None, 3))
    if not len(p):
        raise InputError("the scan has no points", path=path, field="points")
    o = check_array(origin, "origin", shape=(3,))
    sight = unit(o - p)
    tris = (np.empty((0, 3), np.int32) if triangles is None else
            check_array(triangles, "triangles", shape=(None, 3), dtype=np.int64).astype(np.int32))
    if normals is not None:
        n = unit(check_array(normals, "normals", shape=(len(p), 3)))
    elif len(tris):
        n = vertex_normals(p, tris)
        n[np.einsum("ij,ij->i", n, sight) < 0] *= -1
    elif len(p) >= 3:
        from reconstruct.surface.meshing import estimate_normals

        n = estimate_normals(p, o, neighbours=min(neighbours, len(p)))
    else:
        n = sight.copy()
    conf = np.clip(np.einsum("ij,ij->i", n, sight), 0.0, 1.0)
    return RangeScan(name, p, n, sight, conf, tris, None, o.copy(), path)
