"""Geometry from the turtle: tube meshes for segments, fans for ``{ . }`` polygons.

Tubes are the batched generalized cylinders of :func:`procgen.sweeps.segment_tubes`
(radius = width / 2, tapering from a parent's width to its child's). Polygons (leaves)
are triangulated as fans from their first vertex; they are open surfaces, so a mesh that
includes leaves is not closed. Files are written with :func:`core.io.mesh.write_mesh`
(PLY, OBJ, glTF/GLB by suffix).
"""

from __future__ import annotations

import numpy as np

from procgen.lsystem.turtle import TurtleResult
from procgen.sweeps import segment_tubes

__all__ = ["tube_arrays", "polygon_arrays", "to_mesh"]


def tube_arrays(result: TurtleResult, *, sides: int = 8, caps: bool = True,
                min_radius: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Tube mesh arrays ``(vertices (k, 3) float64, triangles (t, 3) int32)``.

    ``min_radius`` keeps thin branches visible (radius = max(width / 2, min_radius)).
    """
    radii = np.maximum(0.5 * result.widths, float(min_radius))
    return segment_tubes(result.starts, result.ends, result.frames, radii, result.parents,
                         sides=sides, caps=caps)


def polygon_arrays(result: TurtleResult) -> tuple[np.ndarray, np.ndarray]:
    """Fan triangulation of the turtle's polygons (fewer than 3 vertices are dropped)."""
    v = result.polygon_vertices
    ids = result.polygon_ids
    if len(v) == 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int32)
    order = np.argsort(ids, kind="stable")
    v, ids = v[order], ids[order]
    # drop repeated vertices ('.' right after an f that already recorded the point)
    same = np.r_[False, (ids[1:] == ids[:-1]) & np.all(np.abs(v[1:] - v[:-1]) < 1e-12, axis=1)]
    v, ids = v[~same], ids[~same]
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    counts = np.diff(np.r_[starts, len(ids)])
    ntri = np.maximum(counts - 2, 0)
    first = np.repeat(starts, ntri)
    local = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri)
    tris = np.stack([first, first + local + 1, first + local + 2], -1).astype(np.int32)
    return v, tris


def to_mesh(result: TurtleResult, *, sides: int = 8, caps: bool = True, leaves: bool = True,
            min_radius: float = 0.0, colors: bool = True):
    """Tubes (and polygons) as the canonical open3d mesh.

    Parameters
    ----------
    result : TurtleResult
    sides : int
        Tube ring resolution.
    caps : bool
        Close tube ends (each unbranched chain is then watertight).
    leaves : bool
        Include the ``{ . }`` polygons.
    min_radius : float
    colors : bool
        Vertex colours: brown for tubes, green for polygons.

    Raises
    ------
    ValueError
        Nothing was drawn.
    """
    from core.meshes import make_mesh

    v, f = tube_arrays(result, sides=sides, caps=caps, min_radius=min_radius)
    n_tube = len(v)
    if leaves and len(result.polygon_vertices):
        vp, fp = polygon_arrays(result)
        v = np.vstack([v, vp])
        f = np.vstack([f, fp + np.int32(n_tube)])
    if len(f) == 0:
        raise ValueError("result: nothing was drawn (no F segments and no polygons)")
    rgb = None
    if colors:  # brown tubes, green polygons
        rgb = np.empty((len(v), 3))
        rgb[:n_tube] = (0.45, 0.3, 0.15)
        rgb[n_tube:] = (0.2, 0.6, 0.2)
    return make_mesh(v, f, vertex_colors=rgb)
