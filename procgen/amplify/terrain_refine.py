"""Terrain refinement: a mesh resampled to a heightfield becomes the control surface of
constrained diamond-square (the control samples are kept exactly; fractal detail is added
between them).

>>> import numpy as np
>>> from procgen.terrain import heightfield_to_mesh
>>> coarse = heightfield_to_mesh(np.random.default_rng(0).normal(size=(9, 9)) * 0.1,
...                              spacing=0.25)
>>> res = refine_terrain(coarse, rng=np.random.default_rng(1), control_size=9, levels=2)
>>> res.heights.shape, bool(np.array_equal(res.heights[::4, ::4], res.control))
((33, 33), True)

References
----------
D. Saupe, "Algorithms for random fractals", in *The Science of Fractal Images*, 1988.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.meshes import make_mesh
from core.validate import check_int, check_positive, check_range, check_rng
from procgen.amplify.surface import mesh_input
from procgen.fractals.displacement import refine_heightfield
from procgen.terrain import _grid_triangles
from procgen.terrain.erosion import ErosionConfig, erode

__all__ = ["Heightfield", "heightfield_from_mesh", "refine_terrain", "TerrainResult"]


@dataclass
class Heightfield:
    """A mesh resampled on a regular grid (see :mod:`procgen.terrain` for the layout).

    Attributes
    ----------
    heights : (r, c) float64
        Sample ``[i, j]`` at ``(origin[0] + j * spacing, origin[1] + i * spacing)``;
        missing samples are filled from the nearest valid one.
    valid : (r, c) bool
        True where a vertical ray hit the mesh.
    origin : (2,) float64
    spacing : float
    """

    heights: np.ndarray
    valid: np.ndarray
    origin: np.ndarray
    spacing: float


def heightfield_from_mesh(mesh, *, size: int = 33) -> Heightfield:
    """Resample the top surface of ``mesh`` on a grid of ``size`` samples along the longer
    horizontal side of its bounding box (square cells), by vertical ray casting.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
    size : int
        2 to 16385.

    Raises
    ------
    ValueError
        No ray hits the mesh (a degenerate footprint).
    """
    import open3d as o3d
    from scipy import ndimage

    v, f = mesh_input(mesh)
    size = check_int(size, "size", 2, 2 ** 14 + 1)
    lo, hi = v.min(axis=0), v.max(axis=0)
    ext = hi[:2] - lo[:2]
    if ext.max() <= 0:
        raise ValueError("mesh: expected a horizontal extent > 0, got a vertical or point mesh")
    spacing = float(ext.max()) / (size - 1)
    cols = max(int(np.ceil(ext[0] / spacing - 1e-9)) + 1, 2)
    rows = max(int(np.ceil(ext[1] / spacing - 1e-9)) + 1, 2)
    xs = lo[0] + spacing * np.arange(cols)
    ys = lo[1] + spacing * np.arange(rows)
    eps = 1e-7 * float(ext.max())
    X, Y = np.meshgrid(np.clip(xs, lo[0] + eps, hi[0] - eps), np.clip(ys, lo[1] + eps,
                                                                       hi[1] - eps))
    top = hi[2] + 1.0 + float(ext.max())
    rays = np.zeros((X.size, 6), np.float32)
    rays[:, 0], rays[:, 1], rays[:, 2] = X.ravel(), Y.ravel(), top
    rays[:, 5] = -1.0
    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
    tm.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tm)
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().astype(np.float64)
    valid = np.isfinite(t).reshape(rows, cols)
    if not valid.any():
        raise ValueError("mesh: no vertical ray hits the mesh; cannot resample a heightfield")
    z = (top - np.where(np.isfinite(t), t, 0.0)).reshape(rows, cols)
    if not valid.all():
        _, (ii, jj) = ndimage.distance_transform_edt(~valid, return_indices=True)
        z = z[ii, jj]
    return Heightfield(heights=z, valid=valid, origin=lo[:2].copy(), spacing=spacing)


@dataclass
class TerrainResult:
    """What :func:`refine_terrain` made.

    Attributes
    ----------
    mesh : open3d.geometry.TriangleMesh
        The refined terrain (trimmed to the input's footprint when asked).
    heights : ((r - 1) 2**levels + 1, (c - 1) 2**levels + 1) float64
        The refined heightfield; ``heights[::2**levels, ::2**levels] == control`` unless
        it was eroded.
    control : (r, c) float64
        The control surface resampled from the input.
    valid : (r, c) bool
        Control samples that hit the input mesh.
    origin : (2,) float64
    spacing : float
        Fine grid step (metres).
    levels : int
    """

    mesh: object
    heights: np.ndarray
    control: np.ndarray
    valid: np.ndarray
    origin: np.ndarray
    spacing: float
    levels: int


def refine_terrain(mesh, *, rng: np.random.Generator, control_size: int = 33,
                   levels: int = 3, hurst: float = 0.8, sigma: float | None = None,
                   trim: bool = True, erosion: str = "none",
                   erosion_config: ErosionConfig | None = None) -> TerrainResult:
    """Amplify a terrain-like mesh with constrained diamond-square detail.

    The mesh's top surface is resampled on a ``control_size`` grid
    (:func:`heightfield_from_mesh`); that control surface is refined ``levels`` times by
    :func:`procgen.fractals.refine_heightfield`, which keeps every control sample exactly
    and adds fractional-Brownian detail of Hurst exponent ``hurst`` in between.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
    rng : numpy.random.Generator
    control_size : int
        Control samples along the longer horizontal side (2 to 1025).
    levels : int
        Halvings of the grid step (0 to 8).
    hurst : float
        In (0, 1): rough when small.
    sigma : float, optional
        Deviation of the first added displacement in metres; by default it continues the
        control surface's own roughness.
    trim : bool
        Drop the cells outside the input's footprint (a control corner missed the mesh).
    erosion : {'none', 'hydraulic', 'thermal', 'stream-power'}
        Then erode the refined heightfield (:func:`procgen.terrain.erosion.erode`, rates
        from ``erosion_config``): valleys carved by water on a reconstructed ground. The
        control samples are then no longer kept exactly.

    Returns
    -------
    TerrainResult
    """
    rng = check_rng(rng)
    control_size = check_int(control_size, "control_size", 2, 1025)
    levels = check_int(levels, "levels", 0, 8)
    h = check_range(hurst, "hurst", 0.0, 1.0, lo_open=True, hi_open=True)
    s = None if sigma is None else check_positive(sigma, "sigma", allow_zero=True)
    hf = heightfield_from_mesh(mesh, size=control_size)
    fine = refine_heightfield(hf.heights, levels, hurst=h, rng=rng, sigma=s)
    D = 2 ** levels
    step = hf.spacing / D
    fine = erode(fine, spacing=step, kind=erosion, config=erosion_config)
    rows, cols = fine.shape
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    verts = np.stack([hf.origin[0] + jj.ravel() * step, hf.origin[1] + ii.ravel() * step,
                      fine.ravel()], 1)
    tris = _grid_triangles(rows, cols)
    if trim and not hf.valid.all():
        v = hf.valid
        cell_ok = v[:-1, :-1] & v[:-1, 1:] & v[1:, :-1] & v[1:, 1:]
        fine_ok = np.repeat(np.repeat(cell_ok, D, axis=0), D, axis=1)
        tris = tris[np.repeat(fine_ok.ravel(), 2)]
        if len(tris) == 0:
            raise ValueError("mesh: no control cell lies wholly inside the footprint; use "
                             "trim=False or a larger control_size")
        used = np.unique(tris)
        remap = np.full(len(verts), -1, np.int64)
        remap[used] = np.arange(len(used))
        verts, tris = verts[used], remap[tris]
    out = make_mesh(verts, tris)
    return TerrainResult(mesh=out, heights=fine, control=hf.heights, valid=hf.valid,
                         origin=hf.origin, spacing=step, levels=levels)
