"""Before/after renders of amplified meshes with the acquisition renderer.

A shaded view (Lambert, one sun with shadows, ambient) from a look-at camera that
frames the parts' bounding box.
"""

from __future__ import annotations

import numpy as np

from acquire.camera import Camera, frame_camera
from acquire.render.lights import DirectionalLight
from acquire.render.materials import Material
from acquire.render.renderer import render
from acquire.render.scene import RenderScene, SceneObject
from core.meshes import make_mesh, mesh_arrays

__all__ = ["render_parts", "tight_camera"]


def tight_camera(points: np.ndarray, *, width: int, height: int, fov_deg: float,
                 elevation_deg: float, azimuth_deg: float, fill: float = 0.9) -> Camera:
    """A look-at camera from the given direction, as close as it can be with every point
    inside the central ``fill`` of the image (the bounding sphere's framing, pulled in:
    a flat scene seen from above fills the frame instead of a quarter of it)."""
    p = np.asarray(points, float)
    if len(p) > 20000:
        p = p[np.linspace(0, len(p) - 1, 20000).astype(np.int64)]
    far = frame_camera(p, width=width, height=height, fov_deg=fov_deg,
                       elevation_deg=elevation_deg, azimuth_deg=azimuth_deg, margin=1.0)
    lo, hi = p.min(0), p.max(0)
    center = 0.5 * (lo + hi)
    eye0 = far.center

    def fits(k: float) -> bool:
        cam = Camera.look_at(center + k * (eye0 - center), center, width=width, height=height,
                             fov_deg=fov_deg)
        uv, z = cam.project(p)
        if not np.all(z > 0):
            return False
        mx, my = (1 - fill) / 2 * width, (1 - fill) / 2 * height
        return bool(np.all((uv[:, 0] >= mx) & (uv[:, 0] <= width - mx) & (uv[:, 1] >= my)
                           & (uv[:, 1] <= height - my)))

    lo_k, hi_k = 0.05, 1.0
    if not fits(hi_k):
        return far
    for _ in range(20):
        mid = 0.5 * (lo_k + hi_k)
        lo_k, hi_k = (lo_k, mid) if fits(mid) else (mid, hi_k)
    return Camera.look_at(center + hi_k * (eye0 - center), center, width=width, height=height,
                          fov_deg=fov_deg)


def render_parts(parts, *, width: int = 320, height: int = 240, elevation_deg: float = 30.0,
                 azimuth_deg: float = -60.0, fov_deg: float = 45.0,
                 camera: Camera | None = None) -> np.ndarray:
    """Render ``parts`` (a list of ``(mesh, rgb albedo)`` or ``(mesh, rgb albedo,
    material fields)``, e.g. ``{"brdf": "dielectric", "roughness": 0.4}``) to an
    ``(h, w, 3) uint8`` image.

    ``camera`` defaults to :func:`tight_camera` of all the parts' vertices.
    """
    objects = []
    allv = []
    for k, (mesh, color, *fields) in enumerate(parts):
        v, f = mesh_arrays(mesh)
        if len(f) == 0:
            continue
        allv.append(v)
        mat = Material(albedo=np.asarray(color, float), **(fields[0] if fields else {}))
        objects.append(SceneObject(name=f"part{k}", mesh=make_mesh(v, f), object_id=k,
                                   material=mat))
    if not objects:
        raise ValueError("parts: expected at least one mesh with triangles")
    if camera is None:
        camera = tight_camera(np.vstack(allv), width=width, height=height, fov_deg=fov_deg,
                              elevation_deg=elevation_deg, azimuth_deg=azimuth_deg)
    sun = DirectionalLight(direction=np.array([-0.4, 0.5, -1.0]), intensity=0.9)
    scene = RenderScene(objects, lights=[sun], ambient=0.25,
                        background=np.array([0.82, 0.86, 0.9]))
    rad = render(scene, camera, supersample=2).radiance
    srgb = np.clip(rad, 0.0, 1.0) ** (1 / 2.2)
    return (srgb * 255 + 0.5).astype(np.uint8)


def turntable(parts, path, *, frames: int = 36, width: int = 480, height: int = 360,
              elevation_deg: float = 30.0, fov_deg: float = 45.0, fps: float = 12.0):
    """A turntable animation of ``parts`` about +z (``.mp4`` or ``.gif``): ``frames``
    views one full turn apart, each framed as :func:`render_parts` frames the first."""
    from scanamp.animation.render import write_frames

    allv = np.vstack([mesh_arrays(p[0])[0] for p in parts])
    azimuths = -60.0 + 360.0 * np.arange(frames) / frames
    cams = [tight_camera(allv, width=width, height=height, fov_deg=fov_deg,
                         elevation_deg=elevation_deg, azimuth_deg=a) for a in azimuths]
    # one distance for every view: the farthest any view needs, so the scene does not pump
    center = 0.5 * (allv.min(0) + allv.max(0))
    dist = max(float(np.linalg.norm(c.center - center)) for c in cams)
    fixed = []
    for c in cams:
        d = c.center - center
        fixed.append(Camera.look_at(center + dist * d / np.linalg.norm(d), center, width=width,
                                    height=height, fov_deg=fov_deg))
    images = (render_parts(parts, camera=c) for c in fixed)
    return write_frames(images, path, fps=fps, total=frames)


def contact_sheet(images, captions, *, columns: int = 4, width: int = 320) -> np.ndarray:
    """Images (paths or arrays) side by side, ``columns`` a row, each scaled to ``width``
    and captioned underneath; an ``(h, w, 3) uint8`` sheet."""
    import cv2

    from core.io.image import read_image

    tiles = []
    for img, text in zip(images, captions, strict=True):
        a = read_image(img) if not isinstance(img, np.ndarray) else img
        a = cv2.resize(a[..., :3], (width, round(a.shape[0] * width / a.shape[1])),
                       interpolation=cv2.INTER_AREA)
        bar = np.full((24, width, 3), 255, np.uint8)
        cv2.putText(bar, text, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (40, 40, 40), 1,
                    cv2.LINE_AA)
        tiles.append(np.vstack([a, bar]))
    h = max(t.shape[0] for t in tiles)
    tiles = [np.vstack([t, np.full((h - t.shape[0], width, 3), 255, np.uint8)]) for t in tiles]
    tiles += [np.full((h, width, 3), 255, np.uint8)] * (-len(tiles) % columns)
    rows = [np.hstack(tiles[i:i + columns]) for i in range(0, len(tiles), columns)]
    return np.vstack(rows)
