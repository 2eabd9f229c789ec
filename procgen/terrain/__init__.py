"""Terrain: heightfields and the water that shapes them.

:mod:`~procgen.terrain.heightfield` (heightfields to meshes, water by a level, fractal
and tileable generators), :mod:`~procgen.terrain.flow` (D8 routing, drainage area,
priority-flood lake filling), :mod:`~procgen.terrain.erosion` (stream-power, hydraulic
and thermal erosion), :mod:`~procgen.terrain.metrics` (the geomorphometry that tells
land from noise) and :mod:`~procgen.terrain.materials` (ground materials and colours).
"""

from procgen.terrain.heightfield import (
    _grid_triangles,  # noqa: F401  (the grid layout, shared with procgen.amplify)
    check_grid_size,
    fractal_terrain,
    heightfield_to_mesh,
    mean_slope,
    mountain_relief,
    tileable_terrain,
    water_mesh,
)

__all__ = ["heightfield_to_mesh", "water_mesh", "fractal_terrain", "tileable_terrain",
           "mountain_relief", "mean_slope", "check_grid_size"]
