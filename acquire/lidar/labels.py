"""Part labels of a surveyed world, and their ASPRS LAS classes.

Every triangle of a LiDAR world carries a part code (``SceneObject.part_labels``, uint8,
an index into :data:`PARTS`); every simulated point inherits the code of the triangle it
hit. The LAS classification follows from the part and, for vegetation, the height above
ground (ASPRS LAS 1.4 R15, table 17; the codes are :class:`core.io.las.AsprsClass`):

===========  ====================================================================
part         ASPRS class
===========  ====================================================================
ground       2 ground
trunk,       3 low vegetation (< 0.5 m above ground), 4 medium (< 2 m), 5 high
branch,
leaf,
understory
building     6 building
road         11 road surface
water        9 water
glass        6 building (a window is part of its building)
unlabelled   1 unclassified
===========  ====================================================================

>>> part_code("leaf")
4
>>> asprs_class(np.array([1, 4, 4, 6], np.uint8), np.array([0.0, 0.3, 12.0, 5.0])).tolist()
[2, 3, 5, 6]
"""

from __future__ import annotations

import numpy as np

from core.io.las import AsprsClass
from core.validate import InputError

__all__ = ["PARTS", "VEGETATION_PARTS", "part_code", "asprs_class", "LOW_VEGETATION_M",
           "MEDIUM_VEGETATION_M"]

#: Part names; a part's code is its index (uint8).
PARTS = ("unlabelled", "ground", "trunk", "branch", "leaf", "understory", "building", "road",
         "water", "glass")
#: Parts classed as vegetation by height above ground.
VEGETATION_PARTS = ("trunk", "branch", "leaf", "understory")
#: Vegetation below this height above ground is ASPRS class 3 (low), metres.
LOW_VEGETATION_M = 0.5
#: Vegetation below this height (and above the low limit) is class 4 (medium), metres.
MEDIUM_VEGETATION_M = 2.0
_FIXED = {"unlabelled": AsprsClass.UNCLASSIFIED, "ground": AsprsClass.GROUND,
          "building": AsprsClass.BUILDING, "road": AsprsClass.ROAD_SURFACE,
          "water": AsprsClass.WATER, "glass": AsprsClass.BUILDING}


def part_code(name: str) -> int:
    """The uint8 code of part ``name``; InputError listing every part when unknown."""
    try:
        return PARTS.index(name)
    except ValueError:
        raise InputError(f"expected one of {', '.join(PARTS)}, got {name!r}",
                         field="part") from None


def asprs_class(parts: np.ndarray, height_above_ground: np.ndarray | None = None) -> np.ndarray:
    """ASPRS classes of points from their part codes.

    Parameters
    ----------
    parts : (n,) uint8
        Codes into :data:`PARTS`.
    height_above_ground : (n,) float64, optional
        Metres; splits vegetation into low / medium / high (all high when omitted).

    Returns
    -------
    (n,) uint8
    """
    parts = np.asarray(parts)
    if parts.size and (parts.min() < 0 or parts.max() >= len(PARTS)):
        raise InputError(f"expected part codes in 0 .. {len(PARTS) - 1}, got "
                         f"{int(parts.min())} .. {int(parts.max())}", field="parts")
    lut = np.zeros(len(PARTS), np.uint8)
    for name, cls in _FIXED.items():
        lut[PARTS.index(name)] = cls
    veg = np.isin(parts, [PARTS.index(p) for p in VEGETATION_PARTS])
    out = lut[parts.astype(np.intp)]
    if height_above_ground is None:
        out[veg] = AsprsClass.HIGH_VEGETATION
        return out
    h = np.asarray(height_above_ground, np.float64)
    if h.shape != parts.shape:
        raise InputError(f"expected shape {parts.shape} like parts, got {h.shape}",
                         field="height_above_ground")
    out[veg] = np.where(h[veg] < LOW_VEGETATION_M, AsprsClass.LOW_VEGETATION,
                        np.where(h[veg] < MEDIUM_VEGETATION_M, AsprsClass.MEDIUM_VEGETATION,
                                 AsprsClass.HIGH_VEGETATION))
    return out
