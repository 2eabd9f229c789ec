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
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from acquire.render.splats import render_splats
from core.files import atomic_file
from core.progress import track

log = logging.getLogger(__name__)

__all__ = ["render_animation", "write_frames", "draw_splats", "mesh_background"]


def mesh_background(mesh, camera, *, color=(0.62, 0.6, 0.56), sky=(0.08, 0.09, 0.12),
                    light_dir=(0.4, -0.5, 1.0), ambient: float = 0.25,
                    supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``mesh`` seen by ``camera``, rendered by :func:`acquire.render.renderer.render`.

    One constant grey material, a directional light shining from ``light_dir`` (towards
    the light) with cast shadows, and an ambient term: the backdrop the particles and
    boids are composited over.

    Returns
    -------
    image : (h, w, 3) float64 in [0, 1]
    depth : (h, w) float64
        Z-depth, ``inf`` where nothing was hit (the splat renderer's occlusion input).
    """
    import open3d as o3d

    from acquire.render.lights import DirectionalLight
    from acquire.render.materials import Material
    from acquire.render.renderer import render
    from acquire.render.scene import RenderScene, SceneObject

    to_light = np.asarray(light_dir, float)
    obj = SceneObject("mesh", o3d.geometry.TriangleMesh(mesh),  # a copy: normals added
                      material=Material(albedo=np.asarray(color, float)))
    scene = RenderScene([obj], lights=[DirectionalLight(-to_light, intensity=1.0 - ambient)],
                        ambient=ambient, background=np.asarray(sky, float))
    r = render(scene, camera, supersample=supersample)
    img = np.clip(r.radiance.astype(np.float64), 0.0, 1.0)
    depth = np.where(r.mask, r.depth.astype(np.float64), np.inf)
    return img, depth


def draw_splats(frame: dict, camera, background, background_depth) -> np.ndarray:
    """The default frame hook of :func:`render_animation`: a frame of points as splats.

    ``frame`` holds ``points (n, 3)`` and optionally ``colors (n, 3)`` in [0, 1],
    ``sizes (n,)`` world radii in metres (default 0.01 m) and ``alphas (n,)``.
    """
    return render_splats(frame["points"], camera, colors=frame.get("colors"),
                         sizes=frame.get("sizes", 0.01), alphas=frame.get("alphas", 1.0),
                         background=background, background_depth=background_depth)


def render_animation(frames: Iterable, camera, out_path: str | os.PathLike, *,
                     background: np.ndarray | None = None,
                     background_depth: np.ndarray | None = None, fps: float = 24,
                     quality: float = 7, total: int | None = None,
                     draw: Callable | None = None) -> Path:
    """Render frames (points as splats, or anything ``draw`` renders) to MP4 or GIF.

    Parameters
    ----------
    frames : iterable
        One item per frame, passed to ``draw``; for the default :func:`draw_splats` a
        dict with ``points (n, 3)`` and optionally ``colors``, ``sizes``, ``alphas``
        (``n`` may change from frame to frame).
    camera : acquire.camera.Camera
    out_path : path ending in ``.mp4`` or ``.gif``
    background : (h, w, 3) float64 in [0, 1], optional
        E.g. a rendered scan from :func:`mesh_background`; black when omitted.
    background_depth : (h, w) float64, optional
        Occludes what lies behind the background surface.
    fps : float
    quality : float
        imageio-ffmpeg quality, 0-10 (MP4 only).
    total : int, optional
        Number of frames, for the progress bar.
    draw : callable, optional
        ``draw(frame, camera, background, background_depth) -> (h, w, 3)`` float image
        in [0, 1]; :func:`draw_splats` by default (boids pass oriented glyphs).

    Returns
    -------
    Path
        ``out_path``, written atomically.
    """
    draw = draw_splats if draw is None else draw
    images = (draw(fr, camera, background, background_depth) for fr in frames)
    return write_frames(images, out_path, fps=fps, quality=quality, total=total)


def write_frames(images: Iterable, out_path: str | os.PathLike, *, fps: float = 12.0,
                 quality: float = 7.0, total: int | None = None) -> Path:
    """Encode images (``(h, w, 3)`` float in [0, 1] or uint8) as ``.mp4`` (H.264) or
    ``.gif``, written atomically; ValueError for another suffix or no image."""
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
            for img in track(images, "rendering", total=total):
                u8 = img if img.dtype == np.uint8 else \
                    (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
                if suffix == ".mp4" and (u8.shape[0] % 2 or u8.shape[1] % 2):
                    u8 = np.pad(u8, ((0, u8.shape[0] % 2), (0, u8.shape[1] % 2), (0, 0)),
                                mode="edge")  # yuv420p needs even sizes
                writer.append_data(u8)
                count += 1
        finally:
            writer.close()
        if count == 0:
            raise ValueError("frames: expected at least one frame, got none")
    log.debug("%s: %d frames", out_path.name, count)
    return out_path
