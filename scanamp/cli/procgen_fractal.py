"""``scanamp procgen fractal KIND``: Koch, Sierpinski, Barnsley's fern, Mandelbrot, Julia."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from scanamp.cli._procgen_common import add_output, check_out

NAME = "fractal"
GROUP = "procgen"
OUTPUT = "file"
HELP = "render a deterministic fractal to PNG (koch, sierpinski, fern, mandelbrot, julia)"

log = logging.getLogger(__name__)


@dataclass
class FractalConfig(Config):
    """Options of ``scanamp procgen fractal``."""

    width: int = option(800, unit="px", range="[1, 20000]", help="image width")
    height: int = option(600, unit="px", range="[1, 20000]", help="image height")
    level: int = option(5, range="[0, 12]", help="koch/sierpinski recursion level")
    points: int = option(200_000, range="[1, 100000000]", help="fern: chaos-game points")
    center: tuple[float, float] | None = option(
        None, metavar=("RE", "IM"), help="mandelbrot/julia: view centre (none: -0.5 0 for "
                                         "mandelbrot, 0 0 for julia)")
    zoom: float = option(1.0, range="(0, inf)", help="mandelbrot/julia: magnification")
    max_iter: int = option(256, range="[1, 100000]", help="mandelbrot/julia: iterations")
    c: tuple[float, float] = option((-0.8, 0.156), metavar=("RE", "IM"),
                                    help="julia: the constant c")


CONFIG = FractalConfig


def add_arguments(p):
    p.add_argument("fractal", choices=["koch", "sierpinski", "fern", "mandelbrot", "julia"])
    add_output(p, kind="image")


def _fit(points: np.ndarray, w: int, h: int, margin: float = 0.05) -> np.ndarray:
    """Map 2-D points to pixel coordinates (y up), keeping the aspect ratio."""
    lo = points.min(axis=0)
    hi = points.max(axis=0)
    scale = (1 - 2 * margin) * min(w / max(hi[0] - lo[0], 1e-12), h / max(hi[1] - lo[1], 1e-12))
    mid = (lo + hi) / 2
    px = (points[:, 0] - mid[0]) * scale + w / 2
    py = h / 2 - (points[:, 1] - mid[1]) * scale
    return np.stack([px, py], 1)


def _render(args, c: FractalConfig) -> np.ndarray:
    import cv2

    from procgen import fractals as F

    w, h = c.width, c.height
    kind = args.fractal
    if kind in ("mandelbrot", "julia"):
        if kind == "mandelbrot":
            center = (-0.5, 0.0) if c.center is None else tuple(c.center)
            counts = F.mandelbrot(w, h, center=center, zoom=c.zoom, max_iter=c.max_iter)
        else:
            center = (0.0, 0.0) if c.center is None else tuple(c.center)
            counts = F.julia(w, h, c=tuple(c.c), center=center, zoom=c.zoom,
                             max_iter=c.max_iter)
        return F.colorize_escape(counts)
    img = np.full((h, w, 3), 255, np.uint8)
    shift = 4  # sub-pixel precision for cv2's anti-aliased drawing
    if kind == "koch":
        poly = F.koch_snowflake(c.level)
        pix = np.round(_fit(poly, w, h) * (1 << shift)).astype(np.int32)
        cv2.fillPoly(img, [pix], (200, 225, 250), lineType=cv2.LINE_AA, shift=shift)
        cv2.polylines(img, [pix], True, (20, 40, 120), 1, lineType=cv2.LINE_AA, shift=shift)
    elif kind == "sierpinski":
        tri = F.sierpinski_triangle(c.level)
        pix = _fit(tri.reshape(-1, 2), w, h).reshape(-1, 3, 2)
        pix = np.round(pix * (1 << shift)).astype(np.int32)
        cv2.fillPoly(img, list(pix), (150, 40, 40), lineType=cv2.LINE_AA, shift=shift)
    else:  # fern: point density, green
        pts = F.barnsley_fern(c.points, rng=np.random.default_rng(args.seed))
        pix = np.floor(_fit(pts, w, h)).astype(np.int64)
        ok = (pix[:, 0] >= 0) & (pix[:, 0] < w) & (pix[:, 1] >= 0) & (pix[:, 1] < h)
        dens = np.zeros((h, w))
        np.add.at(dens, (pix[ok, 1], pix[ok, 0]), 1.0)
        t = np.clip(np.log1p(dens) / max(np.log1p(dens.max()), 1e-12), 0, 1)[..., None]
        green = np.array([20.0, 120.0, 30.0])
        img = np.round(255.0 * (1 - t) + green * t).astype(np.uint8)
    return img


def run(args, config: FractalConfig) -> int:
    from core.io.image import write_image

    out = check_out(args.out, (".png",))
    img = _render(args, config)
    write_image(out, img)
    log.info("wrote %s (%d x %d)", out, img.shape[1], img.shape[0])
    return 0
