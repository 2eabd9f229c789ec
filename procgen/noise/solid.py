"""Solid textures for the renderer: points in space -> colours.

Each texture has the signature ``fn(points, *, scale=1.0, seed=None) -> (n, 3) float64``
with colours in [0, 1]; ``scale`` is the feature size in metres (larger: coarser). The
renderer looks them up by name in :data:`SOLID_TEXTURES`. All are multi-octave, so a
surface carries detail at many scales (stereo and SfM need texture to match).

>>> import numpy as np
>>> pts = np.random.default_rng(0).uniform(-1, 1, size=(100, 3))
>>> sorted(SOLID_TEXTURES)
['clouds', 'fire', 'marble', 'rock', 'wood']
>>> c = SOLID_TEXTURES["marble"](pts, scale=0.5)
>>> c.shape, bool(c.min() >= 0 and c.max() <= 1)
((100, 3), True)
"""

from __future__ import annotations

import numpy as np

from core.validate import check_array, check_positive
from procgen.noise.fractal import bias, fbm, ridged, turbulence

__all__ = ["color_ramp", "fire_ramp", "rock", "clouds", "marble_texture", "wood", "fire",
           "SOLID_TEXTURES"]


def color_ramp(t, stops, colors) -> np.ndarray:
    """Piecewise-linear colour ramp.

    Parameters
    ----------
    t : (n,) float
        Positions, clipped to ``[stops[0], stops[-1]]``.
    stops : (k,) float, increasing
    colors : (k, 3) float in [0, 1]

    Returns
    -------
    (n, 3) float64

    >>> color_ramp([0.0, 0.5, 1.0], [0, 1], [[0, 0, 0], [1, 1, 1]]).tolist()
    [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0]]
    """
    s = check_array(stops, "stops", shape=(None,), min_rows=2)
    c = check_array(colors, "colors", shape=(len(s), 3))
    if np.any(np.diff(s) <= 0):
        raise ValueError("stops: expected strictly increasing values")
    tt = np.clip(np.asarray(t, dtype=np.float64).ravel(), s[0], s[-1])
    return np.stack([np.interp(tt, s, c[:, k]) for k in range(3)], axis=1)


_FIRE_STOPS = np.array([0.0, 0.3, 0.55, 0.8, 1.0])
_FIRE_COLORS = np.array([[0.02, 0.0, 0.0], [0.55, 0.04, 0.0], [0.95, 0.35, 0.02],
                         [1.0, 0.8, 0.2], [1.0, 1.0, 0.85]])


def fire_ramp(t) -> np.ndarray:
    """Black-body-like fire colours for intensities ``t`` in [0, 1]: black, red, orange,
    yellow, white. Returns (n, 3) float64."""
    return color_ramp(t, _FIRE_STOPS, _FIRE_COLORS)


def _points(points, scale):
    p = check_array(points, "points", shape=(None, 3))
    s = check_positive(scale, "scale")
    return p / s


def rock(points, *, scale: float = 1.0, seed: int | None = None) -> np.ndarray:
    """Granite-like rock: grey-brown fBm strata, ridged cracks and fine speckle."""
    q = _points(points, scale)
    x, y, z = q.T
    base = 0.5 + 0.5 * fbm(x, y, z, octaves=6, seed=seed)
    strata = 0.5 + 0.5 * np.sin(6.0 * z + 3.0 * fbm(x + 7.1, y, z, octaves=4, seed=seed))
    cracks = ridged(x * 2.0, y * 2.0, z * 2.0, octaves=4, seed=seed) / 2.0
    speck = fbm(x * 16.0, y * 16.0, z * 16.0, octaves=3, seed=seed)
    t = np.clip(0.55 * base + 0.25 * strata + 0.2 * speck, 0.0, 1.0)
    col = color_ramp(t, [0.0, 0.35, 0.6, 1.0],
                     [[0.18, 0.16, 0.14], [0.38, 0.34, 0.3], [0.58, 0.54, 0.48],
                      [0.8, 0.77, 0.72]])
    dark = np.clip(cracks, 0.0, 1.0) ** 3
    return np.clip(col * (1.0 - 0.6 * dark)[:, None], 0.0, 1.0)


def clouds(points, *, scale: float = 1.0, seed: int | None = None) -> np.ndarray:
    """Sky blue with white cumulus: thresholded fBm shaped by Perlin's bias."""
    q = _points(points, scale)
    x, y, z = q.T
    d = np.clip(0.5 + 0.6 * fbm(x, y, z, octaves=7, seed=seed), 0.0, 1.0)
    cover = bias(np.clip((d - 0.45) / 0.55, 0.0, 1.0), 0.7)
    sky = np.array([0.25, 0.45, 0.85])
    white = np.array([0.97, 0.97, 1.0])
    shade = 0.85 + 0.15 * np.clip(0.5 + fbm(x * 4, y * 4, z * 4, octaves=3, seed=seed), 0, 1)
    col = sky * (1.0 - cover)[:, None] + (white * shade[:, None]) * cover[:, None]
    return np.clip(col, 0.0, 1.0)


def marble_texture(points, *, scale: float = 1.0, seed: int | None = None) -> np.ndarray:
    """White marble with dark veins: ``sin(x + turbulence)`` through a colour ramp."""
    q = _points(points, scale)
    x, y, z = q.T
    turb = turbulence(x, y, z, octaves=7, seed=seed)
    v = 0.5 + 0.5 * np.sin(3.0 * (x + 0.5 * y) + 6.0 * turb)
    col = color_ramp(v ** 0.6, [0.0, 0.15, 0.45, 1.0],
                     [[0.12, 0.12, 0.16], [0.45, 0.45, 0.5], [0.82, 0.82, 0.84],
                      [0.96, 0.95, 0.93]])
    grain = 0.06 * fbm(x * 12, y * 12, z * 12, octaves=3, seed=seed)
    return np.clip(col + grain[:, None], 0.0, 1.0)


def wood(points, *, scale: float = 1.0, seed: int | None = None) -> np.ndarray:
    """Wood: growth rings around the z axis, perturbed by fBm, with fine grain."""
    q = _points(points, scale)
    x, y, z = q.T
    r = np.hypot(x, y) * 4.0 + 0.8 * fbm(x * 0.7, y * 0.7, z * 0.2, octaves=4, seed=seed)
    ring = r - np.floor(r)
    ring = ring ** 3
    grain = fbm(x * 20, y * 20, z * 2, octaves=3, seed=seed)
    t = np.clip(ring + 0.15 * grain, 0.0, 1.0)
    return color_ramp(t, [0.0, 1.0], [[0.72, 0.5, 0.28], [0.38, 0.21, 0.09]])


def fire(points, *, scale: float = 1.0, seed: int | None = None) -> np.ndarray:
    """Fire: turbulence through :func:`fire_ramp`, hotter low, flickering upward (z)."""
    q = _points(points, scale)
    x, y, z = q.T
    turb = turbulence(x * 2, y * 2, z * 2, octaves=6, seed=seed)
    height = np.clip(0.5 - 0.25 * z, 0.0, 1.0)
    t = np.clip(height + 0.9 * turb - 0.2, 0.0, 1.0)
    return fire_ramp(t)


SOLID_TEXTURES = {
    "rock": rock,
    "clouds": clouds,
    "marble": marble_texture,
    "wood": wood,
    "fire": fire,
}
"""Solid textures by material kind: ``fn(points (n, 3), *, scale, seed) -> (n, 3)`` in [0, 1]."""
