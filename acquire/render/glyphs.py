"""Oriented glyphs: each agent (boid) drawn as a small filled triangle pointing along
its heading, seen through a :class:`acquire.camera.Camera`.

Computation only: :func:`glyph_triangles` builds the world-space triangles (tip
ahead, base behind, base edge across the view so the glyph faces the camera) and
:func:`render_glyphs` rasterizes them far to near with a per-pixel depth test against a
background (a rendered scan) and optional translucency.

>>> import numpy as np
>>> from acquire.camera import Camera
>>> cam = Camera.look_at([0, -5, 0], [0, 0, 0], width=40, height=30, fov_deg=40)
>>> img = render_glyphs(np.zeros((1, 3)), np.array([[1.0, 0, 0]]), cam, size=0.5)
>>> bool(img[15, 20].sum() > 0), bool(img[0, 0].sum() == 0)
(True, True)
"""

from __future__ import annotations

import numba as nb
import numpy as np

from core.frames import unit
from core.validate import check_array, check_positive

__all__ = ["glyph_triangles", "render_glyphs", "heading_colors"]


def glyph_triangles(points: np.ndarray, headings: np.ndarray, eye: np.ndarray, *,
                    size: float) -> np.ndarray:
    """World-space glyph triangles ``(n, 3, 3)``: tip, left and right base corners.

    Parameters
    ----------
    points : (n, 3) float64
        Glyph centres.
    headings : (n, 3) float64
        Directions (any length; zero gives a degenerate glyph).
    eye : (3,) float64
        Viewer position: the base edge is across the line of sight.
    size : float
        Glyph length (m); the base is half as wide.
    """
    p = check_array(points, "points", shape=(None, 3))
    h = unit(check_array(headings, "headings", shape=(len(p), 3)))
    s = check_positive(size, "size")
    view = p - check_array(eye, "eye", shape=(3,))
    side = unit(np.cross(h, view))
    tip = p + 0.6 * s * h
    back = p - 0.4 * s * h
    return np.stack([tip, back + 0.25 * s * side, back - 0.25 * s * side], axis=1)


def heading_colors(headings: np.ndarray) -> np.ndarray:
    """Colours ``(n, 3)`` in [0, 1] from unit headings (aligned boids share a colour)."""
    h = unit(check_array(headings, "headings", shape=(None, 3)))
    return 0.25 + 0.75 * (0.5 + 0.5 * h)


@nb.njit(cache=True)
def _raster(tri, z, colors, alpha, order, image, depth, use_depth):
    hgt, wid = image.shape[0], image.shape[1]
    for k in range(order.shape[0]):
        i = order[k]
        x0, y0 = tri[i, 0, 0], tri[i, 0, 1]
        x1, y1 = tri[i, 1, 0], tri[i, 1, 1]
        x2, y2 = tri[i, 2, 0], tri[i, 2, 1]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-9:  # degenerate: one pixel at the centre
            cx = int(np.floor((x0 + x1 + x2) / 3 + 0.5))
            cy = int(np.floor((y0 + y1 + y2) / 3 + 0.5))
            if 0 <= cx < wid and 0 <= cy < hgt and not (use_depth and depth[cy, cx] < z[i]):
                for c in range(3):
                    image[cy, cx, c] = alpha * colors[i, c] + (1 - alpha) * image[cy, cx, c]
            continue
        u0 = max(int(np.floor(min(x0, min(x1, x2)))), 0)
        u1 = min(int(np.ceil(max(x0, max(x1, x2)))), wid - 1)
        v0 = max(int(np.floor(min(y0, min(y1, y2)))), 0)
        v1 = min(int(np.ceil(max(y0, max(y1, y2)))), hgt - 1)
        for y in range(v0, v1 + 1):
            for x in range(u0, u1 + 1):
                w0 = ((x1 - x) * (y2 - y) - (x2 - x) * (y1 - y)) / area
                w1 = ((x2 - x) * (y0 - y) - (x0 - x) * (y2 - y)) / area
                w2 = 1.0 - w0 - w1
                if w0 < 0 or w1 < 0 or w2 < 0:
                    continue
                if use_depth and depth[y, x] < z[i]:
                    continue
                shade = 0.75 + 0.25 * w0  # brighter toward the tip
                for c in range(3):
                    image[y, x, c] = (alpha * min(colors[i, c] * shade, 1.0)
                                      + (1 - alpha) * image[y, x, c])


def render_glyphs(points: np.ndarray, headings: np.ndarray, camera, *,
                  size: float = 0.3, colors: np.ndarray | None = None, alpha: float = 1.0,
                  background: np.ndarray | None = None,
                  background_depth: np.ndarray | None = None) -> np.ndarray:
    """Draw oriented triangle glyphs over ``background``.

    Parameters
    ----------
    points, headings : (n, 3) float64
    camera : acquire.camera.Camera
    size : float
        Glyph length in metres.
    colors : (n, 3) float64 in [0, 1], optional
        Default: :func:`heading_colors`.
    alpha : float in [0, 1]
    background : (h, w, 3) float64 in [0, 1], optional
        Black when omitted.
    background_depth : (h, w) float64, optional
        Z-depth of the background (``inf`` where empty): glyphs behind it are hidden.

    Returns
    -------
    (h, w, 3) float64 in [0, 1]
    """
    p = check_array(points, "points", shape=(None, 3))
    hd = check_array(headings, "headings", shape=(len(p), 3))
    if background is None:
        background = np.zeros((camera.height, camera.width, 3))
    img = check_array(background, "background", shape=(camera.height, camera.width, 3)).copy()
    if len(p) == 0:
        return img
    col = heading_colors(hd) if colors is None else check_array(colors, "colors",
                                                               shape=(len(p), 3))
    tri = glyph_triangles(p, hd, camera.center, size=size)
    pix, zz = camera.project(tri.reshape(-1, 3))
    pix = pix.reshape(-1, 3, 2)
    zz = zz.reshape(-1, 3)
    zc = zz.mean(axis=1)
    ok = np.all(zz > 0, axis=1) & np.all(np.isfinite(pix), axis=(1, 2))
    idx = np.nonzero(ok)[0]
    order = idx[np.argsort(-zc[idx], kind="stable")].astype(np.int64)
    if background_depth is None:
        depth, use = np.zeros((1, 1)), False
    else:
        depth = check_array(background_depth, "background_depth", shape=img.shape[:2],
                            finite=False)
        use = True
    _raster(np.ascontiguousarray(pix), zc, np.ascontiguousarray(col, dtype=np.float64),
            float(np.clip(alpha, 0, 1)), order, img, depth, use)
    return img
