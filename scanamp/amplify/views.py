"""Before/after renders of amplified meshes with the acquisition renderer.

A shaded view (Lambert, one sun with shadows, ambient) from a look-at camera that
frames the parts' bounding box.
"""

from __future__ import annotations

import numpy as np

from acquire.camera import Camera
from acquire.lights import DirectionalLight
from acquire.materials import Material
from acquire.render import render
from acquire.scene import RenderScene, SceneObject
from core.meshes import make_mesh, mesh_arrays

__all__ = ["frame_camera", "render_parts"]


def frame_camera(vertices: np.ndarray, *, width: int = 320, height: int = 240,
                 fov_deg: float = 45.0, elevation_deg: float = 30.0,
                 azimuth_deg: float = -60.0, margin: float = 1.1) -> Camera:
    """A look-at camera seeing the bounding sphere of ``vertices (n, 3)`` whole.

    The camera sits at ``elevation_deg`` above the horizon and ``azimuth_deg`` about +z
    (from +x), far enough for the sphere to fit the narrower field of view.
    """
    v = np.asarray(vertices, np.float64).reshape(-1, 3)
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    half = 0.5 * np.radians(fov_deg)
    half_narrow = np.arctan(np.tan(half) * min(1.0, height / width))
    dist = margin * radius / np.sin(half_narrow)
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    eye = centre + dist * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                    np.sin(el)])
    return Camera.look_at(eye, centre, width=width, height=height, fov_deg=fov_deg)


def render_parts(parts, *, width: int = 320, height: int = 240, elevation_deg: float = 30.0,
                 azimuth_deg: float = -60.0, fov_deg: float = 45.0,
                 camera: Camera | None = None) -> np.ndarray:
    """Render ``parts`` (a list of ``(mesh, rgb albedo)``) to an ``(h, w, 3) uint8`` image.

    ``camera`` defaults to :func:`frame_camera` of all the parts' vertices.
    """
    objects = []
    allv = []
    for k, (mesh, color) in enumerate(parts):
        v, f = mesh_arrays(mesh)
        if len(f) == 0:
            continue
        allv.append(v)
        objects.append(SceneObject(name=f"part{k}", mesh=make_mesh(v, f), object_id=k,
                                   material=Material(albedo=np.asarray(color, float))))
    if not objects:
        raise ValueError("parts: expected at least one mesh with triangles")
    if camera is None:
        camera = frame_camera(np.vstack(allv), width=width, height=height, fov_deg=fov_deg,
                              elevation_deg=elevation_deg, azimuth_deg=azimuth_deg)
    sun = DirectionalLight(direction=np.array([-0.4, 0.5, -1.0]), intensity=0.9)
    scene = RenderScene(objects, lights=[sun], ambient=0.25,
                        background=np.array([0.82, 0.86, 0.9]))
    rad = render(scene, camera, supersample=2).radiance
    srgb = np.clip(rad, 0.0, 1.0) ** (1 / 2.2)
    return (srgb * 255 + 0.5).astype(np.uint8)
