"""The one in-memory mesh type and its conversions.

scanamp's canonical mesh is :class:`open3d.geometry.TriangleMesh` (float64
vertices in metres, int32 triangles). Every conversion to pymeshlab or pyvista
lives here and nowhere else; file formats live in :mod:`core.io.mesh`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from core.validate import check_array

if TYPE_CHECKING:  # pragma: no cover
    import open3d as o3d

__all__ = [
    "make_mesh",
    "mesh_arrays",
    "merge_meshes",
    "transform_mesh",
    "to_pymeshlab",
    "from_pymeshlab",
    "to_pyvista",
    "from_pyvista",
    "surface_area",
    "compact",
    "sorted_mesh",
    "submesh",
    "is_closed",
    "unique_edges",
    "edge_lengths",
    "vertex_normals",
    "face_normals",
    "bbox_diagonal",
]


def _o3d():
    import open3d as o3d

    return o3d


def make_mesh(
    vertices: np.ndarray,
    triangles: np.ndarray,
    *,
    vertex_normals: np.ndarray | None = None,
    vertex_colors: np.ndarray | None = None,
    compute_normals: bool = True,
) -> "o3d.geometry.TriangleMesh":
    """Build the canonical mesh.

    Parameters
    ----------
    vertices : (n, 3) float64
    triangles : (m, 3) int
        Counter-clockwise seen from outside (normals point out).
    vertex_normals : (n, 3) float64, optional
    vertex_colors : (n, 3) float64 in [0, 1], optional
    compute_normals : bool
        Compute vertex normals when none are given.
    """
    o3d = _o3d()
    v = check_array(vertices, "vertices", shape=(None, 3))
    f = np.asarray(triangles)
    # int32 (what open3d stores) passes through without a copy; other integers convert
    f = check_array(f, "triangles", shape=(None, 3),
                    dtype=np.int32 if f.dtype == np.int32 else np.int64)
    if f.size:
        lo, hi = int(f.min()), int(f.max())
        if lo < 0 or hi >= len(v):
            raise ValueError(f"triangles: expected indices in [0, {len(v)}), got [{lo}, {hi}]")
    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.ascontiguousarray(v)),
        o3d.utility.Vector3iVector(np.ascontiguousarray(f, dtype=np.int32)),
    )
    if vertex_normals is not None:
        n = check_array(vertex_normals, "vertex_normals", shape=(len(v), 3))
        mesh.vertex_normals = o3d.utility.Vector3dVector(n)
    elif compute_normals and len(f):
        mesh.compute_vertex_normals()
    if vertex_colors is not None:
        c = check_array(vertex_colors, "vertex_colors", shape=(len(v), 3))
        mesh.vertex_colors = o3d.utility.Vector3dVector(np.clip(c, 0.0, 1.0))
    return mesh


def mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(vertices (n, 3) float64, triangles (m, 3) int64)`` copies of a mesh."""
    return (np.asarray(mesh.vertices, dtype=np.float64).copy(),
            np.asarray(mesh.triangles, dtype=np.int64).copy())


def merge_meshes(meshes) -> "o3d.geometry.TriangleMesh":
    """Concatenate meshes into one (colours kept when every part has them)."""
    meshes = list(meshes)
    if not meshes:
        raise ValueError("meshes: expected at least one mesh, got none")
    vs, fs, cs = [], [], []
    offset = 0
    for m in meshes:
        v, f = mesh_arrays(m)
        vs.append(v)
        fs.append(f + offset)
        offset += len(v)
        cs.append(np.asarray(m.vertex_colors) if m.has_vertex_colors() else None)
    colors = np.vstack(cs) if all(c is not None for c in cs) else None
    return make_mesh(np.vstack(vs), np.vstack(fs), vertex_colors=colors)


def transform_mesh(mesh, world_from_local: np.ndarray) -> "o3d.geometry.TriangleMesh":
    """Return a copy of ``mesh`` moved by the 4x4 transform ``world_from_local``."""
    import copy

    T = check_array(world_from_local, "world_from_local", shape=(4, 4))
    out = copy.deepcopy(mesh)
    out.transform(T)
    return out


def compact(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vertices some triangle uses and the triangles renumbered onto them:
    ``(used (k,) int64, triangles (m, 3) int64)``, so ``vertices[used], triangles`` is the
    submesh without unused vertices.

    >>> compact(np.array([[4, 2, 7]]))[1].tolist()
    [[1, 0, 2]]
    """
    used, inverse = np.unique(np.asarray(triangles, np.int64), return_inverse=True)
    return used, inverse.reshape(-1, 3)


def sorted_mesh(mesh, *, recompute_normals: bool = False) -> "o3d.geometry.TriangleMesh":
    """The same surface in an order that depends only on its geometry: vertices sorted by
    (x, y, z) (then colour and normal; coincident twins by the first triangle, in
    geometric order, that uses them), each triangle rotated to start at its smallest
    index (winding kept), the triangles sorted. Any permutation of the vertices or of the
    triangles gives the same bytes. Extractors that walk a hash map (Open3D's
    ``VoxelBlockGrid``) return the same mesh in a different order from run to run, and
    the order of other meshers follows their input; every reconstruction writes its mesh
    in this order.

    Vertex normals are carried over; a mesh without them, or ``recompute_normals=True``,
    gets them computed from the sorted triangles (normals summed over the triangles in
    another order differ in their last bits).

    >>> import open3d as o3d
    >>> m = sorted_mesh(make_mesh(np.array([[1., 0, 0], [0, 0, 0], [0, 1, 0]]),
    ...                           np.array([[0, 2, 1]])))
    >>> np.asarray(m.vertices)[:, :2].tolist(), np.asarray(m.triangles).tolist()
    ([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]], [[0, 2, 1]])
    """
    v, f = mesh_arrays(mesh)
    colors = np.asarray(mesh.vertex_colors) if mesh.has_vertex_colors() else None
    normals = (np.asarray(mesh.vertex_normals)
               if mesh.has_vertex_normals() and not recompute_normals else None)
    key = np.column_stack([v] + [a for a in (colors, normals) if a is not None])
    order = np.lexsort(key.T[::-1])
    k = key[order]
    if len(k) > 1 and np.any(np.all(k[1:] == k[:-1], axis=1)):  # coincident twins
        order = np.lexsort(np.column_stack([key, _first_triangle(v, f)]).T[::-1])
    rank = np.empty(len(v), np.int64)
    rank[order] = np.arange(len(v))
    f = rank[f]
    roll = np.argmin(f, axis=1)
    f = np.take_along_axis(f, (roll[:, None] + np.arange(3)) % 3, axis=1)
    f = f[np.lexsort((f[:, 2], f[:, 1], f[:, 0]))]
    return make_mesh(v[order], f, vertex_colors=None if colors is None else colors[order],
                     vertex_normals=None if normals is None else normals[order],
                     compute_normals=normals is None)


def _first_triangle(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``(n,) int64``: for each vertex, the rank of the first triangle using it when the
    triangles are ordered by their corners' positions (``len(f)`` if none does): what
    tells coincident vertices apart independently of the order of the input."""
    sig = np.full(len(v), len(f), np.int64)
    if not len(f):
        return sig
    place = np.unique(v, axis=0, return_inverse=True)[1].reshape(-1)  # twins share a place
    t = place[f]
    roll = np.argmin(t, axis=1)  # each triangle from its smallest place, winding kept
    t = np.take_along_axis(t, (roll[:, None] + np.arange(3)) % 3, axis=1)
    t_rank = np.unique(t, axis=0, return_inverse=True)[1].reshape(-1)
    np.minimum.at(sig, f.reshape(-1), np.repeat(t_rank, 3))
    return sig


def submesh(vertices: np.ndarray, triangles: np.ndarray):
    """The ``triangles`` of ``vertices`` as their own canonical mesh, unused vertices
    dropped (:func:`compact`).

    >>> len(submesh(np.zeros((9, 3)), np.array([[4, 2, 7]])).vertices)
    3
    """
    used, tris = compact(triangles)
    return make_mesh(np.asarray(vertices)[used], tris)


def surface_area(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Per-triangle areas ``(m,) float64`` of a mesh given as arrays."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(triangles, dtype=np.int64)
    e1 = v[f[:, 1]] - v[f[:, 0]]
    e2 = v[f[:, 2]] - v[f[:, 0]]
    return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


def to_pymeshlab(mesh):
    """Return a ``pymeshlab.MeshSet`` holding ``mesh`` as its current mesh."""
    import pymeshlab

    v, f = mesh_arrays(mesh)
    kwargs = {}
    if mesh.has_vertex_normals():
        kwargs["v_normals_matrix"] = np.asarray(mesh.vertex_normals, dtype=np.float64)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f.astype(np.int32), **kwargs))
    return ms


def from_pymeshlab(ms_or_mesh) -> "o3d.geometry.TriangleMesh":
    """Convert a ``pymeshlab.MeshSet`` (its current mesh) or ``pymeshlab.Mesh``."""
    m = ms_or_mesh.current_mesh() if hasattr(ms_or_mesh, "current_mesh") else ms_or_mesh
    return make_mesh(m.vertex_matrix(), m.face_matrix())


def to_pyvista(mesh):
    """Return a ``pyvista.PolyData`` of ``mesh`` (vertex colours as point data 'rgb')."""
    import pyvista as pv

    v, f = mesh_arrays(mesh)
    faces = np.hstack([np.full((len(f), 1), 3, dtype=np.int64), f]).ravel()
    pd = pv.PolyData(v, faces)
    if mesh.has_vertex_colors():
        pd.point_data["rgb"] = (np.asarray(mesh.vertex_colors) * 255).astype(np.uint8)
    return pd


def from_pyvista(polydata) -> "o3d.geometry.TriangleMesh":
    """Convert a ``pyvista.PolyData`` (triangulated first if needed)."""
    pd = polydata.triangulate()
    faces = np.asarray(pd.faces).reshape(-1, 4)[:, 1:]
    return make_mesh(np.asarray(pd.points, dtype=np.float64), faces)


def is_closed(mesh_or_triangles) -> bool:
    """True if every edge is shared by exactly two triangles with opposite orientation.

    That is a closed, consistently oriented 2-manifold surface (edge-wise), which is what
    inside/outside tests need. Unlike Open3D's ``is_watertight`` it does not test for
    self-intersections, which costs minutes on large meshes.
    """
    f = (np.asarray(mesh_or_triangles.triangles, dtype=np.int64)
         if hasattr(mesh_or_triangles, "triangles") else np.asarray(mesh_or_triangles, np.int64))
    if len(f) == 0:
        return False
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = int(directed.max()) + 1
    key = directed[:, 0] * n + directed[:, 1]
    rev = directed[:, 1] * n + directed[:, 0]
    uniq, counts = np.unique(key, return_counts=True)
    if np.any(counts != 1):  # a directed edge used twice: inconsistent or non-manifold
        return False
    return bool(np.all(np.isin(rev, uniq, assume_unique=False)))


def unique_edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``edges (e, 2)`` (sorted pairs) and ``tri_edges (m, 3)``: edge index of each
    triangle side (side k joins corners k and k + 1)."""
    f = np.asarray(triangles, np.int64)
    sides = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1).reshape(-1, 2)
    sides = np.sort(sides, axis=1)
    n = int(f.max()) + 1 if f.size else 1
    keys, inverse = np.unique(sides[:, 0] * n + sides[:, 1], return_inverse=True)
    edges = np.stack([keys // n, keys % n], axis=1)  # (lo, hi) in lexicographic order
    return edges, inverse.reshape(-1, 3)


def edge_lengths(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Lengths ``(e,)`` of the unique edges."""
    e, _ = unique_edges(triangles)
    return np.linalg.norm(vertices[e[:, 1]] - vertices[e[:, 0]], axis=1)


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


def face_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit face normals ``(m, 3)`` (zero for degenerate triangles)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    norm = np.linalg.norm(fn, axis=1, keepdims=True)
    return np.divide(fn, norm, out=np.zeros_like(fn), where=norm > 0)


def bbox_diagonal(vertices: np.ndarray) -> float:
    """Length of the axis-aligned bounding box diagonal of ``vertices (n, 3)``."""
    v = np.asarray(vertices, np.float64)
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def surface_distance(mesh):
    """``dist(points (n, 3)) -> (n,)``: the unsigned distance to the surface of ``mesh``
    (Open3D's ray-casting scene, float32 inside).

    >>> import open3d as o3d
    >>> d = surface_distance(o3d.geometry.TriangleMesh.create_box(1.0, 1.0, 1.0))
    >>> [round(float(x), 4) for x in d(np.array([[0.5, 0.5, 2.0], [0.5, 0.5, 0.5]]))]
    [1.0, 0.5]
    """
    import open3d as o3d

    v, f = mesh_arrays(mesh)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)),
                        o3d.core.Tensor(f.astype(np.uint32)))

    def dist(points):
        q = o3d.core.Tensor(np.asarray(points, np.float32))
        return scene.compute_distance(q).numpy().astype(np.float64)

    return dist
