"""Water that follows the flow, and ground materials a landscape tool would paint.

**Water.** Lakes fill the depressions to their spill points (priority-flood); rivers run
where the drainage area passes a threshold, their surface above the bed by a depth that
grows as ``A^0.4`` (discharge ``Q ~ A`` and at-a-station depth ``d ~ Q^0.4``, Leopold &
Maddock 1953), so the water surface falls with the river and is level only on lakes.

**Materials** by slope, altitude, flow and exposure, as terrain tools lay them out:
water where there is water; rock on cliffs; scree at the foot of the slopes too steep for
soil; snow above a snow line that drops on shaded slopes; forest floor below the tree line
where the ground is wet (high topographic wetness ``ln(A / tan slope)``); grass elsewhere.
An fBm field breaks every threshold so the borders wander as they do on land.

**Colours** come from procedural solid textures evaluated at the surface points
(:mod:`procgen.noise.solid`): the rock texture for rock, finer grain for scree,
two-tone fBm for grass and forest floor, faint cloud-blue for snow.

>>> import numpy as np
>>> z = np.add.outer(np.linspace(0, 40, 33), np.zeros(33))   # a 51-degree ramp
>>> mat = classify_materials(z, spacing=1.0, seed=0)
>>> sorted(set(MATERIALS[k] for k in np.unique(mat)))   # no soil holds on it
['rock', 'snow', 'water']
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import check_array, check_range
from procgen.noise.fractal import fbm
from procgen.noise.solid import color_ramp, rock
from procgen.terrain.flow import _spacing, fill_depressions, route_flow

__all__ = ["MATERIALS", "WaterSurface", "water_surface", "classify_materials",
           "material_colors", "MATERIAL_RGB"]

#: material names by id
MATERIALS = ("rock", "scree", "grass", "forest floor", "snow", "water")
#: a representative colour of each (legends, flat previews)
MATERIAL_RGB = np.array([[0.45, 0.42, 0.40], [0.62, 0.60, 0.56], [0.38, 0.55, 0.24],
                         [0.24, 0.30, 0.15], [0.94, 0.95, 0.98], [0.18, 0.35, 0.55]])
ROCK, SCREE, GRASS, FOREST, SNOW, WATER = range(6)


@dataclass
class WaterSurface:
    """Where water stands and how high.

    Attributes
    ----------
    level : (rows, cols) float64
        Water surface height; NaN where dry.
    lake, river : (rows, cols) bool
    area : (rows, cols) float64
        Drainage area (m2) on the filled surface.
    """

    level: np.ndarray
    lake: np.ndarray
    river: np.ndarray
    area: np.ndarray


def water_surface(z, *, spacing=1.0, river_area: float | None = None,
                  river_depth: float | None = None, min_lake_depth: float | None = None
                  ) -> WaterSurface:
    """Lakes and rivers of ``z``.

    Parameters
    ----------
    river_area : float, optional
        Drainage area (m2) where a river starts; default 1 % of the terrain's area.
    river_depth : float, optional
        Depth (m) of a river at ``river_area``; default a quarter of the grid step.
    min_lake_depth : float, optional
        Shallower ponds are left dry; default 1 % of the grid step.
    """
    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    total = z.size * dx * dy
    a0 = 0.01 * total if river_area is None else check_range(river_area, "river_area", 0.0,
                                                              lo_open=True)
    d0 = 0.25 * min(dx, dy) if river_depth is None else check_range(river_depth,
                                                                    "river_depth", 0.0)
    lmin = 0.01 * min(dx, dy) if min_lake_depth is None else check_range(
        min_lake_depth, "min_lake_depth", 0.0)
    filled = fill_depressions(z)
    lake = filled - z > lmin
    fl = route_flow(fill_depressions(z, epsilon=1e-12), spacing=(dx, dy))
    river = (fl.area >= a0) & ~lake
    level = np.full(z.shape, np.nan)
    level[lake] = filled[lake]
    level[river] = z[river] + d0 * (fl.area[river] / a0) ** 0.4
    return WaterSurface(level, lake, river, fl.area)


def _slope_deg(z, dx, dy):
    gy, gx = np.gradient(z, dy, dx)
    return np.degrees(np.arctan(np.hypot(gx, gy))), gx, gy


def classify_materials(z, *, spacing=1.0, water: WaterSurface | None = None,
                       snow_line: float = 0.8, tree_line: float = 0.6,
                       sun_azimuth_deg: float = 180.0, seed: int = 0) -> np.ndarray:
    """A material id (:data:`MATERIALS`) per cell.

    Parameters
    ----------
    water : WaterSurface, optional
        Computed when not given.
    snow_line, tree_line : float
        Fractions of the height range (0 lowest, 1 highest).
    sun_azimuth_deg : float
        Where the sun stands, clockwise from +y (north): slopes facing it hold snow less
        (exposure), and the snow line drops on the shaded side.
    seed : int
        Of the fBm that breaks the borders.
    """
    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    snow_line = check_range(snow_line, "snow_line", 0.0, 1.0)
    tree_line = check_range(tree_line, "tree_line", 0.0, 1.0)
    w = water or water_surface(z, spacing=(dx, dy))
    slope, gx, gy = _slope_deg(z, dx, dy)
    span = max(float(z.max() - z.min()), 1e-12)
    alt = (z - z.min()) / span
    az = np.radians(sun_azimuth_deg)
    # exposure: the slope's outward horizontal normal (-grad) toward the sun, times its
    # steepness: +1 a steep slope facing the sun, -1 facing away
    exposure = -(gx * np.sin(az) + gy * np.cos(az)) / np.sqrt(1 + gx ** 2 + gy ** 2)
    rows, cols = z.shape
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    n = fbm(jj * 8.0 / cols + 0.37, ii * 8.0 / rows + 0.71, 0.5, octaves=4, seed=seed)
    wet = np.log(np.maximum(w.area, dx * dy) / (dx * dy)) - np.log(
        np.tan(np.radians(np.maximum(slope, 0.5))))
    out = np.full(z.shape, GRASS, np.int8)
    high = alt + 0.08 * n
    out[(high < tree_line) & (wet > np.median(wet) + 0.5 * n)] = FOREST
    out[(slope > 28 + 4 * n) | ((high > tree_line + 0.05) & (slope > 18 + 4 * n))] = SCREE
    out[slope > 38 + 5 * n] = ROCK
    out[(high - 0.12 * exposure > snow_line) & (slope < 50 + 5 * n)] = SNOW
    out[np.isfinite(w.level)] = WATER
    return out


def material_colors(points, labels, *, scale: float = 1.0, seed: int = 0) -> np.ndarray:
    """RGB in [0, 1] of surface points ``(n, 3)`` of materials ``labels (n,)`` from solid
    textures; ``scale`` is the feature size in metres."""
    p = check_array(points, "points", shape=(None, 3))
    lab = np.asarray(labels).ravel()
    if len(lab) != len(p):
        raise ValueError(f"labels: expected {len(p)} labels, got {len(lab)}")
    q = p / scale
    out = np.empty((len(p), 3))
    grain = 0.5 + 0.5 * fbm(q[:, 0] * 4.0, q[:, 1] * 4.0, q[:, 2] * 4.0, octaves=4,
                            seed=seed + 1)
    patch = 0.5 + 0.5 * fbm(q[:, 0] * 0.5, q[:, 1] * 0.5, q[:, 2] * 0.5, octaves=4,
                            seed=seed + 2)
    m = lab == ROCK
    if m.any():
        out[m] = rock(p[m], scale=scale, seed=seed)
    m = lab == SCREE
    if m.any():
        out[m] = 0.6 * rock(p[m], scale=0.25 * scale, seed=seed) + 0.4 * color_ramp(
            grain[m], [0.0, 1.0], [[0.50, 0.48, 0.45], [0.75, 0.73, 0.68]])
    m = lab == GRASS
    if m.any():
        base = color_ramp(patch[m], [0.0, 0.5, 1.0],
                          [[0.30, 0.45, 0.16], [0.40, 0.56, 0.22], [0.55, 0.58, 0.28]])
        out[m] = base * (0.85 + 0.3 * grain[m, None])
    m = lab == FOREST
    if m.any():
        base = color_ramp(patch[m], [0.0, 0.5, 1.0],
                          [[0.16, 0.22, 0.10], [0.24, 0.30, 0.14], [0.32, 0.26, 0.16]])
        out[m] = base * (0.8 + 0.4 * grain[m, None])
    m = lab == SNOW
    if m.any():
        out[m] = color_ramp(grain[m], [0.0, 1.0], [[0.82, 0.86, 0.93], [0.98, 0.98, 1.0]])
    m = lab == WATER
    if m.any():
        out[m] = color_ramp(patch[m], [0.0, 1.0], [[0.12, 0.28, 0.45], [0.20, 0.40, 0.58]])
    return np.clip(out, 0.0, 1.0)
