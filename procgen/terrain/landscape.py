"""A heightfield made into a landscape: the ground mesh coloured by material, its water as
a mesh of its own, and the heightfield as an elevation raster.

>>> import numpy as np
>>> z = np.add.outer(np.linspace(0, 1, 9), np.linspace(0, 2, 9))
>>> land = build_landscape(z, spacing=10.0, water="flow", seed=0)
>>> len(land.ground.vertices), land.ground.has_vertex_colors()
(81, True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import check_array
from procgen.terrain.flow import _spacing
from procgen.terrain.heightfield import heightfield_to_mesh, water_mesh
from procgen.terrain.materials import (
    MATERIALS,
    classify_materials,
    material_colors,
    water_surface,
)

__all__ = ["Landscape", "build_landscape", "heightfield_raster"]


@dataclass
class Landscape:
    """Meshes of a heightfield.

    Attributes
    ----------
    ground : open3d.geometry.TriangleMesh
        Vertex colours by material (when asked).
    water : open3d.geometry.TriangleMesh or None
        Lakes and rivers (``water="flow"``) or a sheet at a level; None when dry.
    materials : (rows, cols) int8 or None
        Material ids (:data:`procgen.terrain.materials.MATERIALS`).
    shares : dict
        Share of the cells of each material.
    """

    ground: object
    water: object | None
    materials: np.ndarray | None
    shares: dict


def build_landscape(z, *, spacing=1.0, origin=(0.0, 0.0, 0.0), water="flow",
                    materials: bool = True, seed: int = 0) -> Landscape:
    """The ground mesh of ``z`` and its water.

    Parameters
    ----------
    water : "flow", float or None
        ``"flow"``: lakes to their spill points and rivers down the drainage
        (:func:`procgen.terrain.materials.water_surface`); a number: a sheet at that
        level; None: no water.
    materials : bool
        Colour the ground by material with solid textures.
    seed : int
        Of the textures and the material borders.
    """
    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    if isinstance(water, str) and water != "flow":
        raise ValueError(f"water: expected 'flow', a level or None, got {water!r}")
    ground = heightfield_to_mesh(z, spacing=(dx, dy), origin=origin)
    surf = water_surface(z, spacing=(dx, dy)) if water == "flow" else None
    wmesh = None
    if water is not None:
        wmesh = water_mesh(z, surf.level if surf is not None else water, spacing=(dx, dy),
                           origin=origin)
        if len(wmesh.triangles) == 0:
            wmesh = None
    mats, shares = None, {}
    if materials:
        import open3d as o3d

        mats = classify_materials(z, spacing=(dx, dy), water=surf, seed=seed)
        if surf is None:  # water at a level (or none) instead of the flow's
            wet = MATERIALS.index("water")
            mats = np.where(mats == wet, MATERIALS.index("grass"), mats).astype(np.int8)
            if water is not None:
                mats[z < float(water)] = wet
        v = np.asarray(ground.vertices)
        extent = max(dx * (z.shape[1] - 1), dy * (z.shape[0] - 1))
        ground.vertex_colors = o3d.utility.Vector3dVector(
            material_colors(v, mats.ravel(), scale=extent / 40.0, seed=seed))
        shares = {name: float(np.mean(mats == k)) for k, name in enumerate(MATERIALS)}
    return Landscape(ground, wmesh, mats, shares)


def heightfield_raster(z, *, spacing: float, origin=(0.0, 0.0), crs_wkt: str | None = None):
    """``z`` as a :class:`core.io.raster.Raster` (cell ``[0, 0]`` centred at ``origin``,
    square cells of ``spacing`` metres)."""
    from core.io.raster import Raster

    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    if dx != dy:
        raise ValueError(f"spacing: a raster needs square cells, got {dx} x {dy}")
    return Raster(z, x0=float(origin[0]), y0=float(origin[1]), res=dx, crs_wkt=crs_wkt)
