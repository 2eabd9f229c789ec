"""Fixed-radius neighbour search: a uniform grid with points sorted by cell (numba),
and an exact O(n^2) reference.

The grid is the shared path for every pairwise interaction in :mod:`simulate`
(boids' perception, particles' pair forces): :func:`build_grid` counting-sorts the
points by cell (stably, so points in one cell stay in index order), and
:func:`neighbour_lists` returns CSR lists ``(offsets, indices)`` whose rows are sorted
by neighbour index — exactly what :func:`neighbour_lists_reference` returns by
testing every pair. Sums accumulated over either list in row order are therefore
bit-identical, whatever the number of threads.

Distances are compared as ``dx*dx + dy*dy + dz*dz < radius**2`` (strict) in both.

>>> import numpy as np
>>> p = np.array([[0, 0, 0], [0.5, 0, 0], [3, 0, 0.0]])
>>> off, idx = neighbour_lists(p, 1.0)
>>> [idx[off[i]:off[i + 1]].tolist() for i in range(3)]
[[1], [0], []]
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numba as nb
import numpy as np

from core.validate import check_array, check_positive

__all__ = ["CellGrid", "build_grid", "neighbour_lists", "neighbour_lists_reference",
           "threads_for", "PARALLEL_MIN"]

PARALLEL_MIN = 4096  # fewer points than this: compiled kernels run on one thread


@contextlib.contextmanager
def threads_for(n: int):
    """Run numba parallel kernels on one thread while working on fewer than
    :data:`PARALLEL_MIN` items: waking worker threads costs more than such work (far
    more on a busy machine), and the results are the same bytes either way."""
    if n >= PARALLEL_MIN:
        yield
        return
    threads = nb.get_num_threads()
    nb.set_num_threads(1)
    try:
        yield
    finally:
        nb.set_num_threads(threads)

# A grid never holds more cells than this many per point (plus a floor): a few
# far-away points must not allocate a huge empty grid. Cells grow instead, which
# keeps the search exact (a cell at least as wide as the radius is all it needs).
_CELLS_PER_POINT = 8
_MIN_CELLS = 1 << 15


@dataclass(frozen=True)
class CellGrid:
    """Points sorted by cell of a uniform grid.

    Attributes
    ----------
    origin : (3,) float64
        Corner of cell (0, 0, 0).
    cell_size : float
        Edge of a cubic cell, >= the search radius.
    dims : (3,) int64
        Cells along x, y, z.
    cell : (n,) int64
        Flat cell index of each point, ``ix + nx * (iy + ny * iz)``.
    order : (n,) int64
        Point indices sorted by cell; stable, so by index within a cell.
    start : (ncells + 1,) int64
        Points of cell ``c`` are ``order[start[c]:start[c + 1]]``.
    """

    origin: np.ndarray
    cell_size: float
    dims: np.ndarray
    cell: np.ndarray
    order: np.ndarray
    start: np.ndarray


@nb.njit(cache=True)
def _cell_index(points, origin, h, dims, cell):
    nx, ny, nz = dims[0], dims[1], dims[2]
    for i in range(points.shape[0]):
        ix = min(max(np.int64((points[i, 0] - origin[0]) / h), 0), nx - 1)
        iy = min(max(np.int64((points[i, 1] - origin[1]) / h), 0), ny - 1)
        iz = min(max(np.int64((points[i, 2] - origin[2]) / h), 0), nz - 1)
        cell[i] = ix + nx * (iy + ny * iz)


@nb.njit(cache=True)
def _counting_sort(cell, ncells, order, start):
    counts = np.zeros(ncells + 1, np.int64)
    for i in range(cell.shape[0]):
        counts[cell[i] + 1] += 1
    for c in range(ncells):
        counts[c + 1] += counts[c]
    start[:] = counts
    for i in range(cell.shape[0]):  # stable: index order within each cell
        c = cell[i]
        order[counts[c]] = i
        counts[c] += 1


def build_grid(points: np.ndarray, radius: float, *, lo: np.ndarray | None = None,
               hi: np.ndarray | None = None) -> CellGrid:
    """Sort points into a uniform grid whose cells are at least ``radius`` wide.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
        Search radius (> 0).
    lo, hi : (3,) float64, optional
        World box; defaults to the points' bounding box. Points outside are clamped
        into the border cells (the search stays exact).
    """
    pts = check_array(points, "points", shape=(None, 3))
    h = check_positive(radius, "radius")
    n = len(pts)
    lo = pts.min(axis=0) if (lo is None and n) else (np.zeros(3) if lo is None else
                                                      np.asarray(lo, float))
    hi = pts.max(axis=0) if (hi is None and n) else (lo + h if hi is None else
                                                      np.asarray(hi, float))
    with np.errstate(over="ignore"):  # an infinite extent is reported just below
        extent = np.maximum(np.asarray(hi, float) - lo, 0.0)
    if not np.all(np.isfinite(extent)):
        raise ValueError(f"points: expected a finite extent, got {extent.tolist()}")
    limit = max(_CELLS_PER_POINT * n, _MIN_CELLS)
    while True:  # counted in floats: a huge extent must not overflow int64
        dims_f = np.floor(extent / h) + 1.0
        if float(np.prod(dims_f)) <= limit:
            break
        h *= 1.25
    dims = dims_f.astype(np.int64)
    cell = np.empty(n, np.int64)
    _cell_index(pts, np.asarray(lo, float), h, dims, cell)
    ncells = int(np.prod(dims))
    order = np.empty(n, np.int64)
    start = np.empty(ncells + 1, np.int64)
    _counting_sort(cell, ncells, order, start)
    return CellGrid(origin=np.asarray(lo, float), cell_size=float(h), dims=dims, cell=cell,
                    order=order, start=start)


@nb.njit(cache=True, inline="always")
def cell_range(c, dims, axis):
    """Neighbouring cell coordinates ``[lo, hi]`` along ``axis`` of flat cell ``c``."""
    nx, ny = dims[0], dims[1]
    if axis == 0:
        k = c % nx
    elif axis == 1:
        k = (c // nx) % ny
    else:
        k = c // (nx * ny)
    return max(k - 1, 0), min(k + 1, dims[axis] - 1)


@nb.njit(parallel=True, cache=True)
def _walk(points, r2, dims, cell, order, start, fill, offsets, indices, counts):
    """Count (``fill`` False: into ``counts``) or list (into ``indices`` at ``offsets``)
    each point's neighbours, visiting the 27 cells around its own."""
    nx, ny = dims[0], dims[1]
    for i in nb.prange(points.shape[0]):
        c = cell[i]
        x0, x1 = cell_range(c, dims, 0)
        y0, y1 = cell_range(c, dims, 1)
        z0, z1 = cell_range(c, dims, 2)
        m = offsets[i] if fill else 0
        for cz in range(z0, z1 + 1):
            for cy in range(y0, y1 + 1):
                for cx in range(x0, x1 + 1):
                    cc = cx + nx * (cy + ny * cz)
                    for k in range(start[cc], start[cc + 1]):
                        j = order[k]
                        if j == i:
                            continue
                        dx = points[j, 0] - points[i, 0]
                        dy = points[j, 1] - points[i, 1]
                        dz = points[j, 2] - points[i, 2]
                        if dx * dx + dy * dy + dz * dz < r2:
                            if fill:
                                indices[m] = j
                            m += 1
        if fill:
            indices[offsets[i]:m].sort()
        else:
            counts[i] = m


def neighbour_lists(points: np.ndarray, radius: float, *,
                    grid: CellGrid | None = None) -> tuple[np.ndarray, np.ndarray]:
    """All pairs closer than ``radius`` as CSR lists, found on a uniform grid.

    Parameters
    ----------
    points : (n, 3) float64
    radius : float
    grid : CellGrid, optional
        A grid of these points with ``cell_size >= radius`` (built when omitted).

    Returns
    -------
    offsets : (n + 1,) int64
    indices : (m,) int64
        Neighbours of point ``i`` (itself excluded) are
        ``indices[offsets[i]:offsets[i + 1]]``, sorted ascending.
    """
    pts = check_array(points, "points", shape=(None, 3))
    r = check_positive(radius, "radius")
    if grid is None:
        grid = build_grid(pts, r)
    elif grid.cell_size < r or len(grid.cell) != len(pts):
        raise ValueError(f"grid: expected a grid of these {len(pts)} points with cells >= {r}, "
                         f"got {len(grid.cell)} points and cells of {grid.cell_size}")
    counts = np.empty(len(pts), np.int64)
    offsets = np.zeros(len(pts) + 1, np.int64)
    args = (pts, r * r, grid.dims, grid.cell, grid.order, grid.start)
    with threads_for(len(pts)):
        _walk(*args, False, offsets, np.empty(0, np.int64), counts)
        np.cumsum(counts, out=offsets[1:])
        indices = np.empty(int(offsets[-1]), np.int64)
        _walk(*args, True, offsets, indices, counts)
    return offsets, indices


def neighbour_lists_reference(points: np.ndarray, radius: float, *,
                              block: int = 1024) -> tuple[np.ndarray, np.ndarray]:
    """The same lists as :func:`neighbour_lists` by testing all n^2 pairs (numpy)."""
    pts = check_array(points, "points", shape=(None, 3))
    r = check_positive(radius, "radius")
    rows = []
    counts = np.zeros(len(pts), np.int64)
    for a in range(0, len(pts), block):
        b = min(a + block, len(pts))
        d = pts[None, :, :] - pts[a:b, None, :]
        d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
        close = d2 < r * r
        close[np.arange(b - a), np.arange(a, b)] = False
        i, j = np.nonzero(close)  # row-major: sorted by i, then j
        counts[a:b] = np.bincount(i, minlength=b - a)
        rows.append(j)
    offsets = np.zeros(len(pts) + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    indices = np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64)
    return offsets, indices
