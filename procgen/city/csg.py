"""Constructive solid geometry of simple solids (boxes, vertical cylinders; union and
difference) evaluated as a signed distance field and meshed with marching cubes (VTK through
pyvista): the city's street furniture and the test oracle of closed-form volumes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Box", "Cylinder", "Union", "Difference", "csg_mesh"]

@dataclass(frozen=True)
class Box:
    """Axis-aligned box: ``center (3,)``, ``half (3,)`` half extents."""

    center: tuple
    half: tuple

    def sdf(self, p):
        q = np.abs(p - np.asarray(self.center)) - np.asarray(self.half)
        return (np.linalg.norm(np.maximum(q, 0), axis=-1)
                + np.minimum(np.max(q, axis=-1), 0))

    def bounds(self):
        c, h = np.asarray(self.center), np.asarray(self.half)
        return c - h, c + h


@dataclass(frozen=True)
class Cylinder:
    """Vertical cylinder: ``center (3,)`` of its axis, ``radius``, ``half_height``."""

    center: tuple
    radius: float
    half_height: float

    def sdf(self, p):
        d = p - np.asarray(self.center)
        q = np.stack([np.hypot(d[..., 0], d[..., 1]) - self.radius,
                      np.abs(d[..., 2]) - self.half_height], -1)
        return (np.linalg.norm(np.maximum(q, 0), axis=-1)
                + np.minimum(np.max(q, axis=-1), 0))

    def bounds(self):
        c = np.asarray(self.center)
        h = np.array([self.radius, self.radius, self.half_height])
        return c - h, c + h


@dataclass(frozen=True)
class Union:
    parts: tuple

    def sdf(self, p):
        return np.min([s.sdf(p) for s in self.parts], axis=0)

    def bounds(self):
        b = [s.bounds() for s in self.parts]
        return np.min([x[0] for x in b], axis=0), np.max([x[1] for x in b], axis=0)


@dataclass(frozen=True)
class Difference:
    a: object
    b: object

    def sdf(self, p):
        return np.maximum(self.a.sdf(p), -self.b.sdf(p))

    def bounds(self):
        return self.a.bounds()


def csg_mesh(solid, *, voxel: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Mesh a CSG tree: sample its signed distance on a grid, marching cubes at 0.

    Returns ``(vertices (k, 3) float64, triangles (t, 3) int64)``, outward oriented.
    """
    import pyvista as pv

    lo, hi = solid.bounds()
    lo = lo - 2 * voxel
    hi = hi + 2 * voxel
    dims = np.ceil((hi - lo) / voxel).astype(int) + 1
    grid = pv.ImageData(dimensions=tuple(dims), spacing=(voxel,) * 3, origin=tuple(lo))
    pts = np.asarray(grid.points)
    grid.point_data["d"] = solid.sdf(pts)
    surf = grid.contour([0.0], scalars="d").triangulate().clean()
    v = np.asarray(surf.points, np.float64)
    f = np.asarray(surf.faces).reshape(-1, 4)[:, 1:].astype(np.int64)
    from procgen.sweeps import mesh_volume

    if len(f) and mesh_volume(v, f) < 0:
        f = f[:, ::-1].copy()
    return v, f


