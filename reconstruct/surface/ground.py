"""Ground and objects: which part of a reconstruction (up along +z) is the ground.

A morphological ground filter, as airborne-LiDAR processing does it (Zhang et al. 2003,
the progressive morphological filter, in one step): the lowest surface height in every
cell of a grid over the scene, opened (grey erosion then dilation) with a window wider
than the objects, is the ground's height; a vertex within ``tolerance`` of it, or below
it, is ground, anything standing higher is an object. The window and tolerance are
fractions of the scene's bounding-box diagonal, so one setting serves a table-top scan
and a city block.

>>> import numpy as np
>>> from procgen.terrain import heightfield_to_mesh
>>> from core.meshes import mesh_arrays
>>> hf = np.zeros((41, 41)); hf[18:23, 18:23] = 0.3       # a 0.2 m block on a 2 m plain
>>> v, f = mesh_arrays(heightfield_to_mesh(hf, spacing=0.05))
>>> g = ground_mask(v, f)
>>> bool(g[v[:, 2] == 0.0].all()), bool((~g[v[:, 2] > 0.29]).all())
(True, True)

Reference: K. Zhang et al., "A progressive morphological filter for removing nonground
measurements from airborne LIDAR data", IEEE TGRS 41(4), 2003. doi:10.1109/TGRS.2003.810682
"""

from __future__ import annotations

import numpy as np

from core.meshes import bbox_diagonal

__all__ = ["ground_mask"]


def ground_mask(vertices: np.ndarray, triangles: np.ndarray, *, cell: float = 0.01,
                window: float = 0.12, tolerance: float = 0.015) -> np.ndarray:
    """``(n,) bool``: the ground vertices of a mesh whose up is +z.

    The defaults, on the demo scene's true surface (a rolling terrain with a tree, a shell
    and an organic object on it): 99 % of the terrain's vertices are ground, 3.6 % of the
    objects' (their feet) too.

    Parameters
    ----------
    vertices, triangles : arrays
    cell : float
        Grid cell, as a fraction of the bounding-box diagonal.
    window : float
        Opening window (wider than any object that is not ground), fraction of the diagonal.
    tolerance : float
        Height above the opened ground still counted as ground, fraction of the diagonal.
    """
    from scipy import ndimage

    v = np.asarray(vertices, np.float64)
    diag = bbox_diagonal(v)
    if len(v) == 0 or diag == 0:
        return np.ones(len(v), bool)
    h = max(cell * diag, 1e-12)
    lo = v[:, :2].min(axis=0)
    ij = np.floor((v[:, :2] - lo) / h).astype(np.int64)
    shape = tuple(ij.max(axis=0) + 1)
    zmin = np.full(shape, np.inf)
    np.minimum.at(zmin, (ij[:, 0], ij[:, 1]), v[:, 2])
    empty = ~np.isfinite(zmin)
    if empty.any():  # fill empty cells with their nearest filled cell's height
        idx = ndimage.distance_transform_edt(empty, return_distances=False,
                                             return_indices=True)
        zmin = zmin[tuple(idx)]
    size = max(int(round(window * diag / h)) | 1, 3)
    ground = ndimage.grey_opening(zmin, size=(size, size))
    return v[:, 2] <= ground[ij[:, 0], ij[:, 1]] + tolerance * diag
