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


@nb.njit(cache=True, inline="always")
def _heap_push(key, val, size, k, v):
    """Push ``(k, v)`` on the binary min-heap ``key, val`` of ``size`` items (ties by v)."""
    i = size
    key[i] = k
    val[i] = v
    while i > 0:
        p = (i - 1) // 2
        if key[p] < key[i] or (key[p] == key[i] and val[p] <= val[i]):
            break
        key[p], key[i] = key[i], key[p]
        val[p], val[i] = val[i], val[p]
        i = p
    return size + 1


@nb.njit(cache=True, inline="always")
def _heap_pop(key, val, size):
    """Remove the smallest item; returns the new size (the item was at index 0)."""
    size -= 1
    key[0] = key[size]
    val[0] = val[size]
    i = 0
    while True:
        l = 2 * i + 1
        if l >= size:
            break
        m = l
        r = l + 1
        if r < size and (key[r] < key[l] or (key[r] == key[l] and val[r] < val[l])):
            m = r
        if key[i] < key[m] or (key[i] == key[m] and val[i] <= val[m]):
            break
        key[m], key[i] = key[i], key[m]
        val[m], val[i] = val[i], val[m]
        i = m
    return size


@nb.njit(cache=True)
def _priority_flood(z, boundary, eps):
    r, c = z.shape
    n = r * c
    out = z.copy()
    closed = ~np.isfinite(z)
    key = np.empty(n)
    val = np.empty(n, np.int64)
    size = 0
    pit = np.empty(n, np.int64)
    for i in range(r):
        for j in range(c):
            if boundary[i, j]:
                size = _heap_push(key, val, size, out[i, j], i * c + j)
                closed[i, j] = True
    p_head = 0
    p_tail = 0
    while size > 0 or p_tail > p_head:
        if p_tail > p_head:
            k = pit[p_head]
            p_head += 1
        else:
            k = val[0]
            size = _heap_pop(key, val, size)
        i, j = k // c, k % c
        zk = out[i, j]
        lift = zk + eps * (abs(zk) + 1.0) if eps > 0 else zk
        for di in range(-1, 2):
            for dj in range(-1, 2):
                ii, jj = i + di, j + dj
                if ii < 0 or jj < 0 or ii >= r or jj >= c or closed[ii, jj]:
                    continue
                closed[ii, jj] = True
                if out[ii, jj] <= lift:
                    out[ii, jj] = lift
                    pit[p_tail] = ii * c + jj
                    p_tail += 1
                else:
                    size = _heap_push(key, val, size, out[ii, jj], ii * c + jj)
        if p_tail == p_head:
            p_head = p_tail = 0
    return out


@nb.njit(cache=True)
def _pits(z, boundary):
    """Flat indices of interior cells with no strictly lower neighbour."""
    r, c = z.shape
    out = np.empty(r * c, np.int64)
    m = 0
    for i in range(1, r - 1):
        for j in range(1, c - 1):
            if boundary[i, j] or not np.isfinite(z[i, j]):
                continue
            low = False
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    if z[i + di, j + dj] < z[i, j]:
                        low = True
            if not low:
                out[m] = i * c + j
                m += 1
    return out[:m]


@nb.njit(cache=True)
def _fill_from_pits(out, boundary, eps, pits, max_cells):
    """Fill the depressions holding ``pits`` in place, each from its pit outward: grow a
    region by its lowest neighbour (a priority flood seeded at the pit) until the next
    cell is lower than the highest one taken (past the rim) or on the boundary: the spill
    point; then raise the region by Priority-Flood+epsilon from the spill point. Returns
    False when a region outgrows ``max_cells`` (the caller then floods globally)."""
    r, c = out.shape
    n = r * c
    key = np.empty(n)
    val = np.empty(n, np.int64)
    mark = np.zeros(n, np.int64)
    inreg = np.zeros(n, np.int64)
    stamp = 0
    for p in pits:
        pi, pj = p // c, p % c
        low = False
        for di in range(-1, 2):
            for dj in range(-1, 2):
                if out[pi + di, pj + dj] < out[pi, pj]:
                    low = True
        if low:
            continue  # drained by an earlier fill
        stamp += 1
        size = _heap_push(key, val, 0, out[pi, pj], p)
        mark[p] = stamp
        level = -np.inf
        spill = -1
        taken = 0
        while size > 0:
            h = key[0]
            k = val[0]
            size = _heap_pop(key, val, size)
            ki, kj = k // c, k % c
            if h < level or boundary[ki, kj]:
                spill = k
                break
            level = max(level, h)
            inreg[k] = stamp
            taken += 1
            if taken > max_cells:
                return False
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    ii, jj = ki + di, kj + dj
                    q = ii * c + jj
                    if mark[q] != stamp and np.isfinite(out[ii, jj]):
                        mark[q] = stamp
                        size = _heap_push(key, val, size, out[ii, jj], q)
        if spill < 0:
            return False
        # Priority-Flood+epsilon over the region, from the spill point
        size = _heap_push(key, val, 0, out[spill // c, spill % c], spill)
        while size > 0:
            k = val[0]
            size = _heap_pop(key, val, size)
            ki, kj = k // c, k % c
            zk = out[ki, kj]
            lift = zk + eps * (abs(zk) + 1.0) if eps > 0 else zk
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    ii, jj = ki + di, kj + dj
                    if ii < 0 or jj < 0 or ii >= r or jj >= c:
                        continue
                    q = ii * c + jj
                    if inreg[q] != stamp:
                        continue
                    inreg[q] = 0
                    if out[ii, jj] <= lift:
                        out[ii, jj] = lift
                    size = _heap_push(key, val, size, out[ii, jj], q)
    return True


def drain(z, boundary, eps: float, *, local_share: float = 0.01) -> np.ndarray:
    """``z`` with every depression filled (Priority-Flood+epsilon): from each pit when
    there are few (a surface that already drains but for some pits: fast), else over the
    whole grid."""
    pits = _pits(z, boundary)
    if len(pits) == 0:
        return z
    if len(pits) <= local_share * z.size:
        out = z.copy()
        for _ in range(8):
            if not _fill_from_pits(out, boundary, eps, pits, max(z.size // 10, 1)):
                break
            pits = _pits(out, boundary)
            if len(pits) == 0:
                return out
    return _priority_flood(z, boundary, eps)


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
