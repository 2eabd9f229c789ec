"""Points to surface: normals oriented toward the sensor, screened Poisson, density trim.

Shared by every reconstruction kind (laser, stereo, structured light, SfM). Screened
Poisson (Kazhdan & Hoppe 2013) as Open3D implements it, single-threaded so that the
same points give the same mesh; vertices whose octree density is in the lowest
``density_quantile`` are removed (Poisson closes the surface everywhere, inventing
sheets where no sample supports it).

References
----------
M. Kazhdan, H. Hoppe, "Screened Poisson surface reconstruction", ACM TOG 32(3), 2013,
doi:10.1145/2487228.2487237.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from core.validate import check_array

log = logging.getLogger(__name__)

__all__ = ["MeshingOptions", "estimate_normals", "remove_outliers", "poisson_mesh",
           "points_to_mesh"]


@dataclass(frozen=True)
class MeshingOptions(Config):
    """Options of :func:`points_to_mesh`."""

    depth: int = option(9, help="Poisson octree depth (voxel = bounding cube / 2**depth)",
                        range="[4, 12]")
    density_quantile: float = option(0.02, help="fraction of lowest-density vertices trimmed",
                                     range="[0, 1)")
    normal_neighbours: int = option(24, help="k of the k-NN normal fit", range="[3, 1000]")
    outlier_neighbours: int = option(20, help="k of the statistical outlier test (0 = off)",
                                     range="[0, 1000]")
    outlier_std: float = option(2.5, help="points farther than mean + std * sigma of their "
                                "k-NN mean distance are dropped", range="(0, inf)")
    trim_distance: float = option(0.0, unit="m", help="also drop mesh vertices farther than "
                                  "this from every input point (0 = off)", range="[0, inf)")


def _cloud(points, normals=None):
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    if normals is not None:
        pc.normals = o3d.utility.Vector3dVector(normals)
    return pc


def remove_outliers(points: np.ndarray, *, neighbours: int = 20,
                    std: float = 2.5) -> np.ndarray:
    """Indices ``(m,) int64`` of the points kept by Open3D's statistical outlier test."""
    p = check_array(points, "points", shape=(None, 3))
    if neighbours <= 0 or len(p) <= neighbours:
        return np.arange(len(p))
    _, idx = _cloud(p).remove_statistical_outlier(int(neighbours), float(std))
    return np.asarray(idx, np.int64)


def estimate_normals(points: np.ndarray, viewpoints: np.ndarray, *,
                     neighbours: int = 24) -> np.ndarray:
    """Unit normals ``(n, 3)`` by k-NN plane fits, each turned toward its viewpoint.

    Parameters
    ----------
    points : (n, 3) float64
    viewpoints : (n, 3) or (3,) float64
        Where each point was seen from (the sensor's centre for that measurement).
    """
    import open3d as o3d

    p = check_array(points, "points", shape=(None, 3), min_rows=3)
    v = np.asarray(viewpoints, float)
    v = np.broadcast_to(v, p.shape) if v.shape == (3,) else check_array(
        v, "viewpoints", shape=(len(p), 3))
    pc = _cloud(p)
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(int(neighbours)))
    n = np.asarray(pc.normals).copy()
    flip = np.einsum("ij,ij->i", n, v - p) < 0
    n[flip] *= -1
    return n


def poisson_mesh(points: np.ndarray, normals: np.ndarray, *, depth: int = 9,
                 density_quantile: float = 0.02, trim_distance: float = 0.0):
    """Screened Poisson surface, trimmed by density (and distance to the samples).

    Returns
    -------
    mesh : open3d.geometry.TriangleMesh
    densities : (v,) float64
        Octree density of each kept vertex.
    """
    import open3d as o3d

    p = check_array(points, "points", shape=(None, 3), min_rows=4)
    n = check_array(normals, "normals", shape=(len(p), 3))
    mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        _cloud(p, n), depth=int(depth), n_threads=1)
    dens = np.asarray(dens)
    drop = dens < np.quantile(dens, density_quantile) if density_quantile > 0 else np.zeros(
        len(dens), bool)
    if trim_distance > 0:
        from scipy.spatial import cKDTree

        dist, _ = cKDTree(p).query(np.asarray(mesh.vertices), k=1)
        drop |= dist > trim_distance
    mesh.remove_vertices_by_mask(drop)
    mesh.remove_unreferenced_vertices()
    mesh.remove_degenerate_triangles()
    mesh.compute_vertex_normals()
    return mesh, dens[~drop]


def points_to_mesh(points: np.ndarray, viewpoints: np.ndarray,
                   options: MeshingOptions | None = None) -> dict:
    """The whole chain: outliers out, normals toward the sensor, Poisson, trim.

    Returns
    -------
    dict with ``mesh`` (open3d TriangleMesh), ``points (m, 3)``, ``normals (m, 3)``,
    ``kept (m,) int64`` (indices into the input), ``densities``.
    """
    opt = options or MeshingOptions()
    p = check_array(points, "points", shape=(None, 3))
    if len(p) < 10:
        raise RuntimeError(f"meshing: only {len(p)} points, too few for a surface")
    kept = remove_outliers(p, neighbours=opt.outlier_neighbours, std=opt.outlier_std)
    v = np.asarray(viewpoints, float)
    v = v if v.shape == (3,) else v[kept]
    nrm = estimate_normals(p[kept], v, neighbours=opt.normal_neighbours)
    mesh, dens = poisson_mesh(p[kept], nrm, depth=opt.depth,
                              density_quantile=opt.density_quantile,
                              trim_distance=opt.trim_distance)
    log.debug("meshing: %d points -> %d kept -> %d triangles", len(p), len(kept),
              len(mesh.triangles))
    return {"mesh": mesh, "points": p[kept], "normals": nrm, "kept": kept, "densities": dens}
