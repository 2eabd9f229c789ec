"""Where water goes on a heightfield: D8 flow routing, drainage area, depression filling.

Every cell drains to its steepest-descent neighbour among eight (D8, O'Callaghan & Mark
1984), its *receiver*; a cell with no lower neighbour is its own receiver (a pit, or an
outlet on the boundary). The *stack* (Braun & Willett 2013) lists cells so that each comes
after its receiver: drainage area accumulates walking it backwards, and an implicit
erosion solve walks it forwards, both in O(n). Depressions fill to their spill point by
priority-flood (Barnes et al. 2014): the filled surface is what a lake's level is.

Cells are indexed flat, ``k = i * cols + j``, on the layout of
:mod:`procgen.terrain.heightfield`. NaN cells are outside the terrain (nodata); the grid
edge and the cells beside NaN are the boundary, where water leaves.

>>> import numpy as np
>>> z = np.full((4, 4), 3.0)
>>> z[1:3, 1:3] = 1.0; z[0, 3] = 2.0          # a pit, its lowest rim cell at 2
>>> fill_depressions(z)[1:3, 1:3].tolist()    # filled to its spill point
[[2.0, 2.0], [2.0, 2.0]]
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numba as nb
import numpy as np

from core.validate import check_array, check_positive

__all__ = ["FlowRouting", "route_flow", "d8_receivers", "stack_order", "accumulate",
           "fill_depressions", "boundary_mask", "lake_depth", "NEIGHBOURS"]

#: the eight D8 offsets (di, dj)
NEIGHBOURS = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)],
                      np.int64)


def boundary_mask(z: np.ndarray) -> np.ndarray:
    """The grid edge and every finite cell with a NaN neighbour: where water leaves."""
    finite = np.isfinite(z)
    b = np.zeros(z.shape, bool)
    b[0, :] = b[-1, :] = b[:, 0] = b[:, -1] = True
    pad = np.pad(~finite, 1, constant_values=False)
    r, c = z.shape
    for di, dj in NEIGHBOURS:
        b |= pad[1 + di:1 + di + r, 1 + dj:1 + dj + c]
    return b & finite


@nb.njit(cache=True)
def _receivers(z, boundary, dx, dy):
    r, c = z.shape
    n = r * c
    rec = np.arange(n)
    dist = np.zeros(n)
    diag = np.sqrt(dx * dx + dy * dy)
    for i in range(r):
        for j in range(c):
            k = i * c + j
            if boundary[i, j] or not np.isfinite(z[i, j]):
                continue
            best = 0.0
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    if di == 0 and dj == 0:
                        continue
                    ii, jj = i + di, j + dj
                    if not np.isfinite(z[ii, jj]):
                        continue
                    d = diag if di != 0 and dj != 0 else (dx if di == 0 else dy)
                    s = (z[i, j] - z[ii, jj]) / d
                    if s > best:
                        best = s
                        rec[k] = ii * c + jj
                        dist[k] = d
    return rec, dist


def d8_receivers(z, *, spacing=1.0) -> tuple[np.ndarray, np.ndarray]:
    """Each cell's steepest-descent neighbour (flat index) and the distance to it.

    Boundary cells, NaN cells and cells with no strictly lower neighbour (pits, flats) are
    their own receivers, at distance 0.
    """
    z = check_array(z, "heights", shape=(None, None), finite=False)
    dx, dy = _spacing(spacing)
    return _receivers(z, boundary_mask(z), dx, dy)


@nb.njit(cache=True)
def _stack(rec):
    n = len(rec)
    ndon = np.zeros(n, np.int64)
    for k in range(n):
        if rec[k] != k:
            ndon[rec[k]] += 1
    start = np.zeros(n + 1, np.int64)
    for k in range(n):
        start[k + 1] = start[k] + ndon[k]
    donors = np.empty(max(start[n], 1), np.int64)
    fill = start[:n].copy()
    for k in range(n):
        if rec[k] != k:
            donors[fill[rec[k]]] = k
            fill[rec[k]] += 1
    stack = np.empty(n, np.int64)
    todo = np.empty(n, np.int64)
    m = 0
    for base in range(n):
        if rec[base] != base:
            continue
        top = 0
        todo[0] = base
        top = 1
        while top > 0:
            top -= 1
            k = todo[top]
            stack[m] = k
            m += 1
            for q in range(start[k], start[k + 1]):
                todo[top] = donors[q]
                top += 1
    return stack


def stack_order(receivers) -> np.ndarray:
    """Cells ordered so that every cell comes after its receiver (Braun & Willett 2013):
    a depth-first walk of the donor trees from each base level (a self-receiving cell)."""
    rec = np.asarray(receivers, np.int64)
    if rec.ndim != 1 or (len(rec) and (rec.min() < 0 or rec.max() >= len(rec))):
        raise ValueError("receivers: expected a 1-D array of indices into itself")
    return _stack(rec)


@nb.njit(cache=True)
def _accumulate(rec, stack, weight):
    out = weight.copy()
    for q in range(len(stack) - 1, -1, -1):
        k = stack[q]
        if rec[k] != k:
            out[rec[k]] += out[k]
    return out


def accumulate(receivers, stack, weight) -> np.ndarray:
    """Sum ``weight`` down the flow: each cell's value plus everything draining to it
    (drainage area when ``weight`` is the cell area)."""
    return _accumulate(np.asarray(receivers, np.int64), np.asarray(stack, np.int64),
                       np.asarray(weight, np.float64).ravel().copy())


@nb.njit(cache=True)
def _priority_flood(z, boundary, eps):
    r, c = z.shape
    out = z.copy()
    closed = ~np.isfinite(z)
    heap = [(0.0, 0)]
    heap.pop()
    pit = np.empty(r * c, np.int64)
    for i in range(r):
        for j in range(c):
            if boundary[i, j]:
                heapq.heappush(heap, (out[i, j], i * c + j))
                closed[i, j] = True
    p_head = 0
    p_tail = 0
    while len(heap) > 0 or p_tail > p_head:
        if p_tail > p_head:
            k = pit[p_head]
            p_head += 1
        else:
            _, k = heapq.heappop(heap)
        i, j = k // c, k % c
        zk = out[i, j]
        for di in range(-1, 2):
            for dj in range(-1, 2):
                ii, jj = i + di, j + dj
                if ii < 0 or jj < 0 or ii >= r or jj >= c or closed[ii, jj]:
                    continue
                closed[ii, jj] = True
                lift = zk + eps * (abs(zk) + 1.0) if eps > 0 else zk
                if out[ii, jj] <= lift:
                    out[ii, jj] = lift
                    pit[p_tail] = ii * c + jj
                    p_tail += 1
                else:
                    heapq.heappush(heap, (out[ii, jj], ii * c + jj))
        if p_tail == p_head:
            p_head = p_tail = 0
    return out


def fill_depressions(z, *, epsilon: float = 0.0) -> np.ndarray:
    """Raise every depression to its spill point (priority-flood, Barnes et al. 2014).

    With ``epsilon > 0`` (relative: a cell is raised ``epsilon * (|z| + 1)`` above the cell
    it spills to) the filled flats keep a gradient toward their outlet, so every cell then
    has a strictly lower neighbour (Priority-Flood+epsilon); with 0 lakes are level.
    """
    z = check_array(z, "heights", shape=(None, None), finite=False)
    eps = check_positive(epsilon, "epsilon", allow_zero=True)
    return _priority_flood(z, boundary_mask(z), eps)


def lake_depth(z) -> np.ndarray:
    """Water depth of the lakes that fill the depressions to their spill points (0 dry)."""
    z = check_array(z, "heights", shape=(None, None), finite=False)
    d = fill_depressions(z) - z
    return np.where(np.isfinite(d), d, 0.0)


@dataclass
class FlowRouting:
    """D8 routing of a heightfield.

    Attributes
    ----------
    receivers, distance : (n,) int64, float64
        Each cell's receiver (flat index) and the distance to it (0 for base levels).
    stack : (n,) int64
        Cells, each after its receiver.
    area : (rows, cols) float64
        Drainage area in square metres (the cell's own included).
    shape : (rows, cols)
    """

    receivers: np.ndarray
    distance: np.ndarray
    stack: np.ndarray
    area: np.ndarray
    shape: tuple

    def slope(self, z) -> np.ndarray:
        """Slope to the receiver (0 at base levels), ``(rows, cols)``."""
        zf = np.asarray(z, np.float64).ravel()
        s = np.zeros_like(zf)
        m = self.distance > 0
        s[m] = (zf[m] - zf[self.receivers[m]]) / self.distance[m]
        return s.reshape(self.shape)


def route_flow(z, *, spacing=1.0) -> FlowRouting:
    """D8 receivers, stack order and drainage area of ``z`` as it is (no filling)."""
    z = check_array(z, "heights", shape=(None, None), finite=False)
    dx, dy = _spacing(spacing)
    rec, dist = _receivers(z, boundary_mask(z), dx, dy)
    stack = _stack(rec)
    w = np.where(np.isfinite(z), dx * dy, 0.0).ravel()
    area = _accumulate(rec, stack, w).reshape(z.shape)
    return FlowRouting(rec, dist, stack, area, z.shape)


def _spacing(spacing) -> tuple[float, float]:
    s = np.broadcast_to(np.asarray(spacing, np.float64), (2,))
    return (check_positive(float(s[0]), "spacing"), check_positive(float(s[1]), "spacing"))
