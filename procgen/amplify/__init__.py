"""Mesh amplification operators: procedural detail added to a (reconstructed) mesh.

- :func:`displace` — subdivide to a target edge length, displace along normals by fBm,
  turbulence or ridged noise relative to the local scale, optionally masked by slope or
  curvature.
- :func:`refine_terrain` — a mesh resampled to a heightfield is the control surface of
  constrained diamond-square (control samples kept exactly).
- :func:`scatter_plants` — stochastic L-system plants from one grammar, planted by
  density, slope and altitude rules.
- :func:`grow_vines` — tubes swept along noise-driven walks on the surface.
- :func:`snow_cover` — a snow layer where the surface is level enough and sees the sky.
- :func:`hypertexture_mesh` — the mesh's signed distance plus noise, re-meshed.
- :func:`lay_city` — a procedural city fitted over a ground and laid on its relief.

Every operator takes the canonical mesh, keyword-only options and ``rng``, and returns a
small result object holding the new mesh and what a test needs to check it.
"""

from procgen.amplify.city_layout import CityLayout, lay_city
from procgen.amplify.displacement import DisplaceResult, displace, subdivide_to_edge
from procgen.amplify.hyper import HyperResult, hypertexture_mesh
from procgen.amplify.plants import TREE_GRAMMAR, ScatterResult, grow_variants, scatter_plants
from procgen.amplify.snow import SnowResult, snow_cover
from procgen.amplify.terrain_refine import (
    Heightfield,
    TerrainResult,
    heightfield_from_mesh,
    refine_terrain,
)
from procgen.amplify.vines import VineResult, grow_vines, surface_walks

__all__ = [
    "displace", "subdivide_to_edge", "DisplaceResult",
    "refine_terrain", "heightfield_from_mesh", "Heightfield", "TerrainResult",
    "scatter_plants", "grow_variants", "TREE_GRAMMAR", "ScatterResult",
    "grow_vines", "surface_walks", "VineResult",
    "snow_cover", "SnowResult",
    "hypertexture_mesh", "HyperResult",
    "lay_city", "CityLayout",
]
