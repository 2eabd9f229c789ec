"""Sampling: points uniform by area on a triangle mesh, and voxel thinning of point sets.

>>> import numpy as np
>>> v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
>>> pts, nrm = sample_surface(v, np.array([[0, 1, 2]]), 4, rng=np.random.default_rng(0))
>>> pts.shape, nrm[0].tolist()
((4, 3), [0.0, 0.0, 1.0])
"""

from __future__ import annotations

import numpy as np

from core.validate import check_array

__all__ = ["sample_surface", "voxel_thin"]


def sample_surface(vertices: np.ndarray, triangles: np.ndarray, n: int, *,
                   rng: np.random.Generator, return_index: bool = False):
    """Sample ``n`` points uniformly by area on a triangle mesh.

    Parameters
    ----------
    vertices : (v, 3) float64
    triangles : (m, 3) int
    n : int
        Number of samples (0 gives empty arrays).
    rng : numpy.random.Generator
        Same generator state -> identical samples.
    return_index : bool
        Also return the triangle each sample lies on.

    Returns
    -------
    points : (n, 3) float64
    normals : (n, 3) float64
        Unit face normals of the triangles sampled (orientation as wound).
    index : (n,) int64
        Only with ``return_index``.

    Raises
    ------
    ValueError
        ``n > 0`` on a mesh of zero total area.
    """
    v = check_array(vertices, "vertices", shape=(None, 3))
    f = check_array(triangles, "triangles", shape=(None, 3), dtype=np.int64)
    if n == 0:
        empty = (np.zeros((0, 3)), np.zeros((0, 3)))
        return (*empty, np.zeros(0, np.int64)) if return_index else empty
    if len(f) == 0:
        raise ValueError("triangles: expected at least 1 rows, got 0")
    tri = v[f]
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    cross = np.cross(e1, e2)
    dbl = np.linalg.norm(cross, axis=1)
    cdf = np.cumsum(dbl)
    if not cdf[-1] > 0:
        raise ValueError("triangles: expected positive total area, got 0")
    # side="right" never lands on a zero-area triangle (its cdf equals its predecessor's)
    idx = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
    np.minimum(idx, len(f) - 1, out=idx)
    uv = rng.random((n, 2))
    flip = uv.sum(axis=1) > 1.0
    uv[flip] = 1.0 - uv[flip]
    points = tri[idx, 0] + uv[:, :1] * e1[idx] + uv[:, 1:] * e2[idx]
    normals = cross[idx] / dbl[idx, None]
    if return_index:
        return points, normals, idx.astype(np.int64)
    return points, normals


def voxel_thin(points: np.ndarray, voxel: float) -> np.ndarray:
    """Indices ``(k,) int64`` (sorted) of the first point in each occupied voxel of size
    ``voxel``."""
    points = np.asarray(points, float)
    keys = np.floor((points - points.min(axis=0)) / voxel).astype(np.int64)
    span = keys.max(axis=0) + 1
    if float(span[0]) * float(span[1]) * float(span[2]) < 2.0**62:
        lin = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
        _, first = np.unique(lin, return_index=True)
    else:  # pragma: no cover - absurd extents
        _, first = np.unique(keys, axis=0, return_index=True)
    return np.sort(first)
