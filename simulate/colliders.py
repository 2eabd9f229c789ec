"""Collision queries against triangle meshes (Open3D's Embree RaycastingScene).

One collider serves particles, cloth and boids: swept-segment casts (so nothing
tunnels), probe rays, signed distance, inside tests and closest points. Embree
works in float32; callers keep a small offset (``skin``) from surfaces.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from core.meshes import is_closed, mesh_arrays
from core.validate import check_array

log = logging.getLogger(__name__)

__all__ = ["MeshCollider", "RayHits"]


@dataclass(frozen=True)
class RayHits:
    """Result of a cast.

    Attributes
    ----------
    t : (n,) float64
        Hit parameter in units of the direction vector's length; ``inf`` where no hit.
    normal : (n, 3) float64
        Unit geometric normal of the hit triangle (outward for CCW meshes); 0 where no hit.
    hit : (n,) bool
    triangle : (n,) int64
        Index of the hit triangle; -1 where no hit.
    """

    t: np.ndarray
    normal: np.ndarray
    hit: np.ndarray
    triangle: np.ndarray


# Inside/outside by the majority of this many ray-parity counts: one ray that grazes an
# edge or a vertex (float32) miscounts, and the point 7 um above a snow-covered scan
# was then "inside" (found by the snow recipe).
_VOTES = 3


class MeshCollider:
    """A static triangle mesh to collide with.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
        Must have at least one triangle. A mesh that is not closed triggers a
        warning: inside/outside (signed distance) is then ill-defined.
    """

    def __init__(self, mesh):
        import open3d as o3d

        v, f = mesh_arrays(mesh)
        if len(f) == 0:
            raise ValueError("mesh: expected a collider mesh with faces, got 0 triangles")
        self.vertices = v
        self.triangles = f
        e1 = v[f[:, 1]] - v[f[:, 0]]
        e2 = v[f[:, 2]] - v[f[:, 0]]
        n = np.cross(e1, e2)
        length = np.linalg.norm(n, axis=1, keepdims=True)
        self.face_normals = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
        self.closed = is_closed(f)
        if not self.closed:
            log.warning("collider mesh is not closed: inside/outside tests are unreliable")
        tm = o3d.t.geometry.TriangleMesh()
        tm.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
        tm.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
        self._scene = o3d.t.geometry.RaycastingScene()
        self._scene.add_triangles(tm)
        lo, hi = v.min(axis=0), v.max(axis=0)
        self.bounds = np.stack([lo, hi])

    def cast(self, origins: np.ndarray, directions: np.ndarray) -> RayHits:
        """Cast rays ``origins + t * directions``.

        For a swept segment from ``x0`` to ``x1`` pass ``directions = x1 - x0``: a
        hit with ``t <= 1`` lies on the segment.

        Parameters
        ----------
        origins, directions : (n, 3) float64
        """
        import open3d as o3d

        o = check_array(origins, "origins", shape=(None, 3))
        d = check_array(directions, "directions", shape=(len(o), 3))
        rays = np.concatenate([o, d], axis=1).astype(np.float32)
        ans = self._scene.cast_rays(o3d.core.Tensor(rays))
        t = ans["t_hit"].numpy().astype(np.float64)
        hit = np.isfinite(t)
        tri = ans["primitive_ids"].numpy().astype(np.int64)
        tri[~hit] = -1
        normal = np.zeros((len(o), 3))
        normal[hit] = self.face_normals[tri[hit]]
        t[~hit] = np.inf
        # Zero-length directions give NaN/garbage in Embree: never a hit.
        still = ~np.any(d != 0, axis=1)
        t[still] = np.inf
        hit &= ~still
        return RayHits(t=t, normal=normal, hit=hit, triangle=np.where(hit, tri, -1))

    def segments_hit(self, rays: np.ndarray) -> np.ndarray:
        """``(n,) bool``: does the segment ``origin + t direction, t in [0, 1]`` meet the mesh?

        ``rays (n, 6) float32``: origins and directions as Open3D takes them, unchecked
        (the fast path of :func:`simulate.collisions.collide`). An any-hit query
        (Embree's occlusion test), cheaper than finding the first hit. Zero directions
        never hit.
        """
        import open3d as o3d

        rays = np.ascontiguousarray(rays, np.float32)
        hit = self._scene.test_occlusions(o3d.core.Tensor(rays), tnear=0.0, tfar=1.0).numpy()
        k = np.nonzero(hit)[0]  # few: check the directions of the hits only
        hit[k] = np.any(rays[k, 3:] != 0, axis=1)
        return hit

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance ``(n,) float64``: negative inside a closed mesh."""
        import open3d as o3d

        p = check_array(points, "points", shape=(None, 3)).astype(np.float32)
        return self._scene.compute_signed_distance(o3d.core.Tensor(p), nsamples=_VOTES).numpy(
        ).astype(np.float64)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Unsigned distance ``(n,) float64`` to the surface."""
        import open3d as o3d

        p = check_array(points, "points", shape=(None, 3)).astype(np.float32)
        return self._scene.compute_distance(o3d.core.Tensor(p)).numpy().astype(np.float64)

    def inside(self, points: np.ndarray) -> np.ndarray:
        """``(n,) bool``: True where a point is inside the (closed) mesh."""
        import open3d as o3d

        p = check_array(points, "points", shape=(None, 3)).astype(np.float32)
        return self._scene.compute_occupancy(o3d.core.Tensor(p), nsamples=_VOTES).numpy() > 0.5

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest surface points ``(n, 3)`` and their unit face normals ``(n, 3)``."""
        import open3d as o3d

        p = check_array(points, "points", shape=(None, 3)).astype(np.float32)
        ans = self._scene.compute_closest_points(o3d.core.Tensor(p))
        tri = ans["primitive_ids"].numpy().astype(np.int64)
        return ans["points"].numpy().astype(np.float64), self.face_normals[tri]
