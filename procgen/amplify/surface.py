"""Surface helpers of the amplification operators.

Arrays in, arrays out: midpoint subdivision and longest-edge bisection that carry
per-vertex attributes, the
local scale of a mesh, slope and curvature. Generic mesh measures (edges, normals,
the bounding-box diagonal) are :mod:`core.meshes`.
"""

from __future__ import annotations

import numpy as np

from core.meshes import mesh_arrays, unique_edges
from core.validate import check_array


def mesh_input(mesh, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, triangles)`` of a mesh with at least one triangle, else ValueError."""
    if not (hasattr(mesh, "vertices") and hasattr(mesh, "triangles")):
        raise ValueError(f"{name}: expected an open3d TriangleMesh, got {type(mesh).__name__}")
    v, f = mesh_arrays(mesh)
    if len(f) == 0:
        raise ValueError(f"{name}: expected a mesh with triangles, got 0 triangles")
    check_array(v, f"{name}.vertices", shape=(None, 3))
    return v, f


def subdivide_midpoint(vertices: np.ndarray, triangles: np.ndarray,
                       attributes: np.ndarray | None = None):
    """One level of midpoint subdivision: every triangle into four.

    Edge midpoints are shared between neighbouring triangles, so closed meshes stay
    closed and every new vertex lies on an old edge (the surface does not move).
    ``attributes (n, k)`` are interpolated linearly (the mean of the edge's ends).

    Returns
    -------
    vertices : (n + e, 3) float64
        The old vertices first, in order, then one per unique edge.
    triangles : (4 m, 3) int64
    attributes : (n + e, k) float64 or None
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    edges, te = unique_edges(f)
    mid = len(v) + te
    nv = np.vstack([v, 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])])
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    ab, bc, ca = mid[:, 0], mid[:, 1], mid[:, 2]
    nf = np.concatenate([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                         np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)])
    na = None
    if attributes is not None:
        at = np.asarray(attributes, np.float64)
        na = np.concatenate([at, 0.5 * (at[edges[:, 0]] + at[edges[:, 1]])])
    return nv, nf, na


def split_long_edges(vertices: np.ndarray, triangles: np.ndarray, target_edge: float,
                     attributes: np.ndarray | None = None, *, max_triangles: int | None = None):
    """Longest-edge bisection (Rivara) until no edge is longer than ``target_edge``.

    Only the edges longer than the target are split (and, so that every split triangle is
    split across its longest side and keeps its shape, the longest edge of each triangle
    that has a split edge): a mesh whose edges vary widely is refined where it is coarse
    and left alone where it is fine. Midpoints are shared between neighbours, so the mesh
    stays conforming and closed meshes stay closed; the surface does not move.
    ``attributes (n, k)`` are interpolated linearly.

    Returns ``(vertices, triangles, attributes, rounds)`` with the old vertices first, in
    order; ``None`` as soon as a round would pass ``max_triangles``.
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    a = None if attributes is None else np.asarray(attributes, np.float64)
    rounds = 0
    while True:
        edges, te = unique_edges(f)
        length = np.linalg.norm(v[edges[:, 1]] - v[edges[:, 0]], axis=1)
        mark = length > target_edge
        if not mark.any():
            return v, f, a, rounds
        # side k joins corners k and k + 1; the longest side of each triangle
        longest = np.argmax(length[te], axis=1)
        long_edge = te[np.arange(len(f)), longest]
        while True:  # closure: a triangle with a split side splits its longest side too
            need = mark[te].any(axis=1) & ~mark[long_edge]
            if not need.any():
                break
            mark[long_edge[need]] = True
        mid = np.full(len(edges), -1, np.int64)
        mid[mark] = len(v) + np.arange(int(mark.sum()))
        v = np.vstack([v, 0.5 * (v[edges[mark, 0]] + v[edges[mark, 1]])])
        if a is not None:
            a = np.concatenate([a, 0.5 * (a[edges[mark, 0]] + a[edges[mark, 1]])])
        f = _bisect(f, te, mark, mid, longest)
        rounds += 1
        if max_triangles is not None and len(f) > max_triangles:
            return None


def _bisect(f: np.ndarray, te: np.ndarray, mark: np.ndarray, mid: np.ndarray,
            longest: np.ndarray) -> np.ndarray:
    """New triangles of one bisection round (orientation kept)."""
    rows = np.arange(len(f))
    # rotate each triangle so its longest side is (a, b): side k joins corners k, k + 1
    a = f[rows, longest]
    b = f[rows, (longest + 1) % 3]
    c = f[rows, (longest + 2) % 3]
    e_bc = te[rows, (longest + 1) % 3]
    e_ca = te[rows, (longest + 2) % 3]
    m_ab = mid[te[rows, longest]]
    m_bc, m_ca = mid[e_bc], mid[e_ca]
    split = m_ab >= 0
    bc, ca = split & mark[e_bc], split & mark[e_ca]
    out = [f[~split]]
    left, right = split & ~ca, split & ~bc  # halves (a, m_ab, c) and (m_ab, b, c) unsplit
    out.append(np.stack([a[left], m_ab[left], c[left]], 1))
    out.append(np.stack([m_ab[right], b[right], c[right]], 1))
    out.append(np.stack([a[ca], m_ab[ca], m_ca[ca]], 1))
    out.append(np.stack([m_ab[ca], c[ca], m_ca[ca]], 1))
    out.append(np.stack([m_ab[bc], b[bc], m_bc[bc]], 1))
    out.append(np.stack([m_ab[bc], m_bc[bc], c[bc]], 1))
    return np.concatenate(out)


def local_edge_length(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Mean length ``(n,)`` of the edges incident to each vertex (the local sample spacing).

    Unused vertices get the mean edge length of the mesh.
    """
    v = np.asarray(vertices, np.float64)
    e, _ = unique_edges(triangles)
    ln = np.linalg.norm(v[e[:, 1]] - v[e[:, 0]], axis=1)
    s = np.bincount(e.ravel(), weights=np.repeat(ln, 2), minlength=len(v))
    c = np.bincount(e.ravel(), minlength=len(v))
    out = np.full(len(v), ln.mean() if len(ln) else 0.0)
    np.divide(s, c, out=out, where=c > 0)
    return out


def slope_deg(normals: np.ndarray) -> np.ndarray:
    """Slope ``(n,)`` in degrees of surfaces with unit ``normals``: 0 flat (facing +z or
    -z), 90 vertical."""
    nz = np.clip(np.abs(np.asarray(normals, np.float64)[:, 2]), 0.0, 1.0)
    return np.degrees(np.arccos(nz))


def curvature(vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Unsigned mean-curvature estimate ``(n,)`` in 1/m from the umbrella operator.

    ``2 |(mean of neighbours - p) . n| / (mean neighbour distance)**2``: exactly ``1/R`` for
    neighbours on a circle of radius R about the normal, 0 on a plane.
    """
    v = np.asarray(vertices, np.float64)
    e, _ = unique_edges(triangles)
    s = np.zeros_like(v)
    np.add.at(s, e[:, 0], v[e[:, 1]])
    np.add.at(s, e[:, 1], v[e[:, 0]])
    c = np.bincount(e.ravel(), minlength=len(v)).astype(np.float64)
    h = local_edge_length(v, triangles)
    off = np.zeros(len(v))
    used = c > 0
    mean = s[used] / c[used, None]
    off[used] = np.abs(np.einsum("ij,ij->i", mean - v[used], normals[used]))
    return np.divide(2.0 * off, h ** 2, out=np.zeros(len(v)), where=h > 0)


def smoothstep(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """0 below ``lo``, 1 above ``hi``, a C1 cubic in between (a step when lo == hi)."""
    x = np.asarray(x, np.float64)
    if hi <= lo:
        return (x >= lo).astype(np.float64)
    t = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)
