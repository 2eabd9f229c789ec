"""Point splatting: particles drawn as Gaussian splats with translucent "over" blending.

Points are projected through a :class:`acquire.camera.Camera`, sorted far to near,
and composited one by one onto a background image: each splat covers the pixels
within three standard deviations of its centre with weight
``alpha * exp(-d^2 / (2 sigma^2))`` and colour ``c``, ``out = w c + (1 - w) out``
(Porter-Duff "over"). A background depth map hides splats behind the background
surface pixel by pixel. The world radius of a particle becomes a pixel radius by
``fx * r / z``.

>>> import numpy as np
>>> img = composite_splats(np.array([[2.0, 2.0]]), np.array([1.0]), np.ones((1, 3)),
...                        np.array([1.0]), np.array([1.0]), np.zeros((5, 5, 3)))
>>> float(img[2, 2, 0])
1.0
"""

from __future__ import annotations

import numba as nb
import numpy as np

from core.validate import check_array

__all__ = ["composite_splats", "render_splats"]


@nb.njit(cache=True)
def _composite(px, py, z, colors, sigma, alphas, order, image, depth, use_depth):
    h, w = image.shape[0], image.shape[1]
    for k in range(order.shape[0]):
        i = order[k]
        s = sigma[i]
        reach = 3.0 * s
        x0 = max(int(np.floor(px[i] - reach)), 0)
        x1 = min(int(np.ceil(px[i] + reach)), w - 1)
        y0 = max(int(np.floor(py[i] - reach)), 0)
        y1 = min(int(np.ceil(py[i] + reach)), h - 1)
        inv = 1.0 / (2.0 * s * s)
        for y in range(y0, y1 + 1):
            dy = y - py[i]
            for x in range(x0, x1 + 1):
                if use_depth and depth[y, x] < z[i]:
                    continue
                dx = x - px[i]
                wgt = alphas[i] * np.exp(-(dx * dx + dy * dy) * inv)
                if wgt < 1e-4:
                    continue
                for c in range(3):
                    image[y, x, c] = wgt * colors[i, c] + (1.0 - wgt) * image[y, x, c]


def composite_splats(pixels: np.ndarray, z: np.ndarray, colors: np.ndarray,
                     radii_px: np.ndarray, alphas: np.ndarray, background: np.ndarray, *,
                     background_depth: np.ndarray | None = None) -> np.ndarray:
    """Composite Gaussian splats already in image space onto ``background``.

    Parameters
    ----------
    pixels : (n, 2) float64
        Splat centres (OpenCV pixel coordinates, pixel centres at integers).
    z : (n,) float64
        Z-depth; splats are drawn far to near, those with ``z <= 0`` are skipped.
    colors : (n, 3) float64 in [0, 1]
    radii_px : (n,) float64
        Splat radius in pixels (the Gaussian's standard deviation is half of it;
        at least 0.5 pixel so that far particles stay visible).
    alphas : (n,) float64 in [0, 1]
        Peak opacity of each splat.
    background : (h, w, 3) float64 in [0, 1]
    background_depth : (h, w) float64, optional
        Z-depth of the background surface (``inf`` where empty); hides splats behind it.

    Returns
    -------
    (h, w, 3) float64
        A new image.
    """
    img = check_array(background, "background", shape=(None, None, 3)).copy()
    px = check_array(pixels, "pixels", shape=(None, 2), finite=False)
    n = len(px)
    zz = check_array(z, "z", shape=(n,), finite=False)
    col = check_array(colors, "colors", shape=(n, 3))
    rad = check_array(radii_px, "radii_px", shape=(n,), finite=False)
    alp = np.clip(check_array(alphas, "alphas", shape=(n,)), 0.0, 1.0)
    ok = (zz > 0) & np.isfinite(zz) & np.all(np.isfinite(px), axis=1) & np.isfinite(rad)
    idx = np.nonzero(ok)[0]
    order = idx[np.argsort(-zz[idx], kind="stable")]
    sigma = np.maximum(0.5 * np.nan_to_num(rad, nan=1.0, posinf=1.0), 0.5)
    if background_depth is None:
        depth = np.zeros((1, 1))
        use = False
    else:
        depth = check_array(background_depth, "background_depth", shape=img.shape[:2],
                            finite=False)
        use = True
    _composite(np.ascontiguousarray(px[:, 0]), np.ascontiguousarray(px[:, 1]), zz,
               np.ascontiguousarray(col), sigma, alp, order.astype(np.int64), img, depth, use)
    return img


def render_splats(points: np.ndarray, camera, *, colors: np.ndarray | None = None,
                  sizes: np.ndarray | float = 0.01, alphas: np.ndarray | float = 1.0,
                  background: np.ndarray | None = None,
                  background_depth: np.ndarray | None = None) -> np.ndarray:
    """Render world points as splats seen by ``camera``.

    Parameters
    ----------
    points : (n, 3) float64
        World positions (metres).
    camera : acquire.camera.Camera
    colors : (n, 3) float64 in [0, 1], optional
        White when omitted.
    sizes : (n,) float64 or float
        World radius of each particle (metres); ``fx * r / z`` pixels on screen.
    alphas : (n,) float64 or float
    background : (h, w, 3) float64 in [0, 1], optional
        Black when omitted; must match the camera's image size.
    background_depth : (h, w) float64, optional
        Z-depth of the background (occludes splats behind it).

    Returns
    -------
    (h, w, 3) float64 in [0, 1]
    """
    p = check_array(points, "points", shape=(None, 3))
    n = len(p)
    if background is None:
        background = np.zeros((camera.height, camera.width, 3))
    bg = check_array(background, "background", shape=(camera.height, camera.width, 3))
    col = np.ones((n, 3)) if colors is None else colors
    r = np.broadcast_to(np.asarray(sizes, np.float64), (n,))
    a = np.broadcast_to(np.asarray(alphas, np.float64), (n,))
    if n == 0:
        return bg.copy()
    pix, z = camera.project(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        rad = camera.fx * r / z
    return composite_splats(pix, z, col, rad, a, bg, background_depth=background_depth)
