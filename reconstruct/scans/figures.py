"""Pictures of a set of scans: the scans coloured by scan (a point-splat render, no
OpenGL needed) and a plot of per-scan residuals.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> p = rng.normal(size=(500, 3)); n = p / np.linalg.norm(p, axis=1, keepdims=True)
>>> img = render_scans([p, p + 3.0], [n, n], size=(80, 60))
>>> img.shape, img.dtype.name
((60, 80, 3), 'uint8')
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["render_scans", "scan_colors", "plot_residuals"]


def scan_colors(n: int) -> np.ndarray:
    """``(n, 3) float64`` distinct colours in [0, 1] (tab20, then golden-angle hues)."""
    from matplotlib import colormaps

    tab = colormaps["tab20"](np.arange(20))[:, :3]
    out = [tab[(2 * k) % 20 + (k // 10) % 2] if k < 20 else
           colormaps["hsv"]((k * 0.618034) % 1.0)[:3] for k in range(n)]
    return np.array(out).reshape(n, 3)


def _view_axes() -> np.ndarray:
    """Rows: image right, image down, into the image: a three-quarter view from above
    (+z up)."""
    az, el = np.radians(35.0), np.radians(25.0)
    fwd = -np.array([np.cos(el) * np.sin(az), -np.cos(el) * np.cos(az), np.sin(el)])
    up = np.array([0.0, 0.0, 1.0])
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    return np.stack([right, down, fwd])


def render_scans(points: Sequence[np.ndarray], normals: Sequence[np.ndarray], *,
                 size: tuple[int, int] = (800, 600), up: np.ndarray | None = None,
                 colors: np.ndarray | None = None) -> np.ndarray:
    """An orthographic splat render of point sets, each in its colour, shaded by normal.

    Parameters
    ----------
    points, normals : sequence of (n_k, 3) float64
        One set per scan, all in one frame.
    size : (width, height)
    up : (3,) float64, optional
        The frame's up direction (default +z).
    colors : (k, 3) float64 in [0, 1], optional

    Returns
    -------
    (height, width, 3) uint8
    """
    from core.frames import rotation_between

    w, h = size
    colors = scan_colors(len(points)) if colors is None else np.asarray(colors, float)
    lift = np.eye(3) if up is None else rotation_between(np.asarray(up, float), [0, 0, 1.0])
    axes = _view_axes() @ lift
    allp = np.concatenate([np.asarray(p, float) for p in points]) if points else np.zeros((0, 3))
    img = np.full((h, w, 3), 255, np.uint8)
    if len(allp) == 0:
        return img
    q = allp @ axes.T
    lo, hi = np.percentile(q[:, :2], [0.2, 99.8], axis=0)  # stray samples do not frame it
    scale = 0.92 * min(w / max(hi[0] - lo[0], 1e-12), h / max(hi[1] - lo[1], 1e-12))
    mid = (lo + hi) / 2
    light = -axes[2] + 0.5 * axes[0] - 0.7 * axes[1]
    light /= np.linalg.norm(light)
    depth = np.full(h * w, np.inf)
    rgb = np.zeros((h * w, 3))
    for k, (p, n) in enumerate(zip(points, normals, strict=True)):
        qq = np.asarray(p, float) @ axes.T
        u = np.round((qq[:, 0] - mid[0]) * scale + w / 2).astype(np.int64)
        v = np.round((qq[:, 1] - mid[1]) * scale + h / 2).astype(np.int64)
        shade = 0.35 + 0.65 * np.abs(np.asarray(n, float) @ light)
        for du, dv in ((0, 0), (1, 0), (0, 1), (1, 1)):  # 2x2 splats close the gaps
            uu, vv = u + du, v + dv
            ok = (uu >= 0) & (uu < w) & (vv >= 0) & (vv < h)
            pix = vv[ok] * w + uu[ok]
            z = qq[ok, 2]
            order = np.lexsort((z, pix))  # nearest first within each pixel
            pix, z, s = pix[order], z[order], shade[ok][order]
            first = np.r_[True, pix[1:] != pix[:-1]]
            pix, z, s = pix[first], z[first], s[first]
            win = z < depth[pix]
            depth[pix[win]] = z[win]
            rgb[pix[win]] = s[win, None] * colors[k]
    seen = np.isfinite(depth)
    flat = img.reshape(-1, 3)
    flat[seen] = np.clip(255 * rgb[seen], 0, 255).astype(np.uint8)
    return img


def plot_residuals(names: Sequence[str], rms: Sequence[float], overlap: Sequence[float],
                   registered: Sequence[bool], *, size=(8.0, 4.0)) -> np.ndarray:
    """A bar chart of each scan's RMS residual (mm) and overlap, as an RGB ``uint8``
    image; unregistered scans are marked."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    x = np.arange(len(names))
    vals = np.array([1000 * r if ok and np.isfinite(r) else 0.0
                     for r, ok in zip(rms, registered, strict=True)])
    colors = scan_colors(len(names))
    ax.bar(x, vals, color=colors, edgecolor="k", linewidth=0.5)
    for k, ok in enumerate(registered):
        if not ok:
            ax.text(k, 0, "not\nregistered", ha="center", va="bottom", fontsize=7, color="r")
    ax.set_ylabel("RMS point-to-plane residual (mm)")
    ax2 = ax.twinx()
    ax2.plot(x, 100 * np.asarray(overlap, float), "k.", label="overlap")
    ax2.set_ylabel("overlap with the other scans (%)")
    ax2.set_ylim(0, 105)
    ax.set_xticks(x, [str(n) for n in names], rotation=60, ha="right", fontsize=7)
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
