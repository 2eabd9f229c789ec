"""Render simulation frames (particles, cloth vertices, boids) to MP4 or GIF.

The glue between :mod:`simulate` (which produces positions per frame) and
:mod:`acquire` (camera, splat renderer); only scanamp imports both.

>>> import numpy as np, tempfile, pathlib
>>> from acquire.camera import Camera
>>> cam = Camera.look_at([0, -3, 1], [0, 0, 0], width=32, height=24, fov_deg=60)
>>> frames = [{"points": np.zeros((1, 3)) + [0, 0, 0.1 * k]} for k in range(3)]
>>> out = render_animation(frames, cam, pathlib.Path(tempfile.mkdtemp()) / "a.gif", fps=10)
>>> out.suffix
'.gif'
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from acquire.splats import render_splats
from procgen.files import atomic_file
from procgen.progress import track

log = logging.getLogger(__name__)

__all__ = ["render_animation", "mesh_background", "frame_camera"]


def mesh_background(mesh, camera, *, color=(0.62, 0.6, 0.56), sky=(0.08, 0.09, 0.12),
                    light_dir=(0.4, -0.5, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """A shaded image and z-depth of ``mesh`` seen by ``camera`` (ray cast, Lambert).

    TODO(lead): replace by ``acquire.render`` once it lands; this is a minimal
    stand-in (one ray per pixel, headlight-free directional light, no shadows).

    Returns
    -------
    image : (h, w, 3) float64 in [0, 1]
    depth : (h, w) float64
        Z-depth, ``inf`` where the ray misses.
    """
    import open3d as o3d

    from procgen.meshes import mesh_arrays

    v, f = mesh_arrays(mesh)
    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
    tm.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tm)
    pix = camera.pixel_grid()
    o, d = camera.rays(pix)
    ans = scene.cast_rays(o3d.core.Tensor(np.concatenate([o, d], 1).astype(np.float32)))
    t = ans["t_hit"].numpy().astype(np.float64)
    n = ans["primitive_normals"].numpy().astype(np.float64)
    hit = np.isfinite(t)
    light = np.asarray(light_dir, float)
    light = light / np.linalg.norm(light)
    # Two-sided Lambert with an ambient term: scans are often open surfaces.
    view = -d / np.linalg.norm(d, axis=1, keepdims=True)
    n = np.where((np.sum(n * view, axis=1) < 0)[:, None], -n, n)
    shade = 0.25 + 0.75 * np.clip(n @ light, 0.0, 1.0)
    img = np.empty((len(pix), 3))
    img[:] = sky
    img[hit] = shade[hit, None] * np.asarray(color, float)[None]
    depth = np.where(hit, t, np.inf)
    h, w = camera.height, camera.width
    return img.reshape(h, w, 3), depth.reshape(h, w)


def frame_camera(points: np.ndarray, *, width: int = 640, height: int = 480,
                 fov_deg: float = 45.0, elevation_deg: float = 20.0, azimuth_deg: float = -90.0,
                 margin: float = 1.15):
    """A look-at camera that frames the bounding box of ``points (n, 3)``."""
    from acquire.camera import Camera

    p = np.asarray(points, float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    lo, hi = (p.min(0), p.max(0)) if len(p) else (-np.ones(3), np.ones(3))
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
    dist = margin * radius / np.sin(np.radians(fov_deg) / 2 * min(1.0, height / width))
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    eye = center + dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return Camera.look_at(eye, center, width=width, height=height, fov_deg=fov_deg)


def render_animation(frames: Iterable[dict], camera, out_path: str | os.PathLike, *,
                     background: np.ndarray | None = None,
                     background_depth: np.ndarray | None = None, fps: float = 24,
                     quality: float = 7, total: int | None = None) -> Path:
    """Render frames of points as splats and encode them as MP4 (H.264) or GIF.

    Parameters
    ----------
    frames : iterable of dict
        Each with ``points (n, 3)`` and optionally ``colors (n, 3)`` in [0, 1],
        ``sizes (n,)`` world radii in metres (default 1 % of nothing: 0.01 m) and
        ``alphas (n,)``; ``n`` may change from frame to frame.
    camera : acquire.camera.Camera
    out_path : path ending in ``.mp4`` or ``.gif``
    background : (h, w, 3) float64 in [0, 1], optional
        E.g. a rendered scan from :func:`mesh_background`; black when omitted.
    background_depth : (h, w) float64, optional
        Occludes particles behind the background surface.
    fps : float
    quality : float
        imageio-ffmpeg quality, 0-10 (MP4 only).
    total : int, optional
        Number of frames, for the progress bar.

    Returns
    -------
    Path
        ``out_path``, written atomically.
    """
    import imageio.v2 as iio

    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise ValueError(f"out_path: expected a .mp4 or .gif file, got {out_path.name!r}")
    if not fps > 0:
        raise ValueError(f"fps: expected a positive number, got {fps!r}")
    with atomic_file(out_path) as tmp:
        if suffix == ".mp4":
            writer = iio.get_writer(tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                    quality=quality, macro_block_size=1,
                                    pixelformat="yuv420p", output_params=["-threads", "1"])
        else:
            writer = iio.get_writer(tmp, format="GIF", mode="I", duration=1000.0 / fps, loop=0)
        try:
            count = 0
            for fr in track(frames, "rendering", total=total):
                img = render_splats(fr["points"], camera, colors=fr.get("colors"),
                                    sizes=fr.get("sizes", 0.01), alphas=fr.get("alphas", 1.0),
                                    background=background, background_depth=background_depth)
                u8 = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
                if suffix == ".mp4" and (u8.shape[0] % 2 or u8.shape[1] % 2):
                    u8 = np.pad(u8, ((0, u8.shape[0] % 2), (0, u8.shape[1] % 2), (0, 0)),
                                mode="edge")  # yuv420p needs even sizes
                writer.append_data(u8)
                count += 1
        finally:
            writer.close()
        if count == 0:
            raise ValueError("frames: expected at least one frame, got none")
    log.info("wrote %s (%d frames)", out_path, count)
    return out_path
