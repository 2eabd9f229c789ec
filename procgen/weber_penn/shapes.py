"""Weber & Penn's crown shapes: the shape ratio of each ``Shape`` (0-7), the pruning
envelope (8), and the taper of a stem's radius (``nTaper``, periodic above 1) and the
trunk's flare.

The shape ratio scales a first-order branch by where it leaves the trunk: ``ratio`` is 1 at
the crown base and 0 at the top (``(length_trunk - offset) / (length_trunk - base)``).

>>> import numpy as np
>>> shape_ratio(0, np.array([0.0, 0.5, 1.0])).round(6).tolist()  # conical: longest at the base
[0.2, 0.6, 1.0]
>>> float(shape_ratio(5, 0.7))                             # flame: widest at 70 %
1.0
"""

from __future__ import annotations

import numpy as np

__all__ = ["SHAPE_NAMES", "shape_ratio", "envelope_ratio", "inside_envelope", "taper_radius",
           "flare_factor"]

SHAPE_NAMES = ("conical", "spherical", "hemispherical", "cylindrical", "tapered cylindrical",
               "flame", "inverse conical", "tend flame", "envelope")


def envelope_ratio(ratio, *, width_peak: float, power_low: float, power_high: float):
    """Shape 8, the pruning envelope: rises as ``(r / (1 - peak))**power_high`` from the top to
    its widest at ``ratio = 1 - peak``, then falls as ``((1 - r) / peak)**power_low`` to the
    crown base; 0 outside [0, 1]."""
    r = np.asarray(ratio, dtype=float)
    top = 1.0 - width_peak
    with np.errstate(divide="ignore", invalid="ignore"):
        hi = np.where(top > 0, np.clip(r / max(top, 1e-12), 0, None), 1.0) ** power_high
        lo = (np.clip(1.0 - r, 0, None) / max(width_peak, 1e-12)) ** power_low
    out = np.where(r < top, hi, lo)
    return np.where((r < 0) | (r > 1), 0.0, out)


def shape_ratio(shape: int, ratio, *, prune: dict | None = None):
    """The length factor of Weber & Penn's ``Shape`` (0-8) at ``ratio`` in [0, 1].

    ``prune`` holds ``PruneWidthPeak``, ``PrunePowerLow``, ``PrunePowerHigh`` for shape 8.
    """
    r = np.asarray(ratio, dtype=float)
    if shape == 0:
        out = 0.2 + 0.8 * r
    elif shape == 1:
        out = 0.2 + 0.8 * np.sin(np.pi * r)
    elif shape == 2:
        out = 0.2 + 0.8 * np.sin(0.5 * np.pi * r)
    elif shape == 3:
        out = np.ones_like(r)
    elif shape == 4:
        out = 0.5 + 0.5 * r
    elif shape == 5:
        out = np.where(r <= 0.7, r / 0.7, (1.0 - r) / 0.3)
    elif shape == 6:
        out = 1.0 - 0.8 * r
    elif shape == 7:
        out = np.where(r <= 0.7, 0.5 + 0.5 * r / 0.7, 0.5 + 0.5 * (1.0 - r) / 0.3)
    elif shape == 8:
        p = prune or {}
        out = envelope_ratio(r, width_peak=p.get("PruneWidthPeak", 0.5),
                             power_low=p.get("PrunePowerLow", 0.5),
                             power_high=p.get("PrunePowerHigh", 0.5))
    else:
        raise ValueError(f"shape: expected 0-8, got {shape!r}")
    return out if np.ndim(out) else float(out)


def inside_envelope(points, *, scale: float, base_size: float, prune: dict):
    """Whether points (relative to the tree's base) lie inside the pruning envelope:
    ``|xy| / scale < PruneWidth * shape_ratio(8, (scale - z) / (scale (1 - BaseSize)))``.

    points : (..., 3) float; returns (...,) bool.
    """
    p = np.asarray(points, dtype=float)
    ratio = (scale - p[..., 2]) / max(scale * (1.0 - base_size), 1e-12)
    width = prune["PruneWidth"] * shape_ratio(8, ratio, prune=prune)
    return np.hypot(p[..., 0], p[..., 1]) / scale < width


def taper_radius(r0, length, z, taper):
    """Radius along a stem of base radius ``r0`` and ``length`` at fraction ``z`` in [0, 1].

    ``taper`` in [0, 1] narrows linearly to ``1 - taper`` of the base at the tip (a cone at
    1); in (1, 2] the stem is a chain of spheres whose bulges deepen toward 2; in (2, 3] the
    periodic bulges keep the full depth (the paper's palm trunk, 2.1).
    """
    r0, length, z = (np.asarray(a, dtype=float) for a in (r0, length, z))
    unit = np.where(taper < 1, taper, np.where(taper < 2, 2.0 - taper, 0.0))
    taper_z = r0 * (1.0 - unit * z)
    if np.all(np.asarray(taper) <= 1):
        return taper_z
    z2 = (1.0 - z) * length
    tz = np.maximum(taper_z, 1e-12)
    depth = np.where((taper < 2) | (z2 < tz), 1.0, taper - 2.0)
    z3 = np.abs(z2 - 2 * tz * np.floor(z2 / (2 * tz) + 0.5))
    bulge = (1 - depth) * taper_z + depth * np.sqrt(np.clip(tz ** 2 - (z3 - tz) ** 2, 0, None))
    out = np.where((taper < 2) & (z3 >= tz), taper_z, bulge)
    return np.where(np.asarray(taper) <= 1, taper_z, out)


def flare_factor(z, flare: float):
    """The trunk's flare at fraction ``z``: ``1 + flare (100**y - 1) / 100`` with
    ``y = max(0, 1 - 8 z)`` (the lowest eighth of the trunk widens)."""
    y = np.clip(1.0 - 8.0 * np.asarray(z, dtype=float), 0, None)
    return 1.0 + flare * (100.0 ** y - 1.0) / 100.0
