"""Surface helpers shared by the amplification operators (private to procgen.amplify).

Arrays in, arrays out: midpoint subdivision that carries per-vertex attributes, vertex
normals, the local scale of a mesh, slope and curvature, area-weighted surface samples.
"""

from __future__ import annotations

import numpy as np

from procgen.meshes import mesh_arrays, surface_area
from procgen.validate import check_array


def check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def check_int(value, name: str, lo: int, hi: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo \
            or (hi is not None and value > hi):
        rng_s = f"[{lo}, {hi}]" if hi is not None else f">= {lo}"
        raise ValueError(f"{name}: expected an integer {rng_s}, got {value!r}")
    return int(value)


def mesh_input(mesh, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, triangles)`` of a mesh with at least one triangle, else ValueError."""
    if not (hasattr(mesh, "vertices") and hasattr(mesh, "triangles")):
        raise ValueError(f"{name}: expected an open3d TriangleMesh, got {type(mesh).__name__}")
    v, f = mesh_arrays(mesh)
    if len(f) == 0:
        raise ValueError(f"{name}: expected a mesh with triangles, got 0 triangles")
    check_array(v, f"{name}.vertices", shape=(None, 3))
    return v, f


def unique_edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``edges (e, 2)`` (sorted pairs) and ``tri_edges (m, 3)``: edge index of each
    triangle side (side k joins corners k and k + 1)."""
    f = np.asarray(triangles, np.int64)
    sides = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1).reshape(-1, 2)
    sides = np.sort(sides, axis=1)
    edges, inverse = np.unique(sides, axis=0, return_inverse=True)
    return edges, inverse.reshape(-1, 3)


def edge_lengths(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Lengths ``(e,)`` of the unique edges."""
    e, _ = unique_edges(triangles)
    return np.linalg.norm(vertices[e[:, 1]] - vertices[e[:, 0]], axis=1)


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


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``(n, 3)`` (zero for unused vertices)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)


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


def sample_surface(vertices: np.ndarray, triangles: np.ndarray, n: int,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points uniform by area: ``points (n, 3)`` and their ``triangle (n,)`` indices."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    area = surface_area(v, f)
    total = area.sum()
    if n == 0 or total <= 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    tri = np.searchsorted(np.cumsum(area) / total, rng.random(n), side="right")
    tri = np.minimum(tri, len(f) - 1)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    a, b, c = v[f[tri, 0]], v[f[tri, 1]], v[f[tri, 2]]
    pts = (1 - s)[:, None] * a + (s * (1 - r2))[:, None] * b + (s * r2)[:, None] * c
    return pts, tri


def face_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit face normals ``(m, 3)`` (zero for degenerate triangles)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    norm = np.linalg.norm(fn, axis=1, keepdims=True)
    return np.divide(fn, norm, out=np.zeros_like(fn), where=norm > 0)


def bbox_diagonal(vertices: np.ndarray) -> float:
    v = np.asarray(vertices, np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
