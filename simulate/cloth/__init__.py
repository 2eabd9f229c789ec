"""Cloth: a spring-mass grid (stretch, shear and bend springs, pins, strain limiting)
colliding with meshes.

- :mod:`simulate.cloth.mass_spring` the cloth, its specification and the grid builder.

>>> from simulate.cloth import grid_cloth
>>> grid_cloth.__name__
'grid_cloth'
"""

from core.lazy import lazy_exports

_EXPORTS = dict.fromkeys(["Cloth", "ClothSpec", "grid_cloth"], "mass_spring")
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
