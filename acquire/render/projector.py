"""A pattern projector: an inverse camera that is also a light.

The projector is a :class:`acquire.camera.Camera` (intrinsics, distortion, pose,
resolution) with an image. A surface point is lit by the pattern value at the
pixel it projects to (bilinear), scaled by ``intensity``, the cosine between the
surface normal and the direction to the projector, and the inverse square of the
distance to the projector centre (a unit intensity gives radiance 1 on a white
surface facing it at 1 m for a white pattern pixel). Shadow rays go toward the
projector centre, so the renderer casts the projector's shadows.

>>> from acquire.camera import Camera
>>> cam = Camera.look_at([0, -1, 0], [0, 0, 0], width=8, height=6)
>>> proj = PatternProjector(cam, np.ones((6, 8)))
>>> proj.irradiance(np.zeros((1, 3)), np.array([[0.0, -1.0, 0.0]])).round(6).tolist()
[[1.0, 1.0, 1.0]]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acquire.camera import Camera
from core.validate import check_array, check_positive

__all__ = ["PatternProjector", "sample_bilinear"]


def sample_bilinear(image: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Bilinear samples ``(n,)`` of ``image (H, W)`` at ``pixels (n, 2)`` (x, y); 0 outside.

    Pixel centres sit at integer coordinates; samples within half a pixel of the
    border clamp to the border pixels.
    """
    H, W = image.shape
    x, y = pixels[:, 0], pixels[:, 1]
    inside = np.isfinite(x) & np.isfinite(y) & (x >= -0.5) & (x <= W - 0.5) & \
        (y >= -0.5) & (y <= H - 0.5)
    xs = np.clip(np.where(inside, x, 0.0), 0, W - 1)
    ys = np.clip(np.where(inside, y, 0.0), 0, H - 1)
    x0 = np.minimum(np.floor(xs).astype(np.int64), W - 2 if W > 1 else 0)
    y0 = np.minimum(np.floor(ys).astype(np.int64), H - 2 if H > 1 else 0)
    x1 = np.minimum(x0 + 1, W - 1)
    y1 = np.minimum(y0 + 1, H - 1)
    fx, fy = xs - x0, ys - y0
    v = (image[y0, x0] * (1 - fx) * (1 - fy) + image[y0, x1] * fx * (1 - fy)
         + image[y1, x0] * (1 - fx) * fy + image[y1, x1] * fx * fy)
    return np.where(inside, v, 0.0)


@dataclass(eq=False)
class PatternProjector:
    """A projector light (see the module docstring).

    Parameters
    ----------
    camera : Camera
        The projector as an inverse camera; its width/height are the projector's
        resolution and ``cam_from_world`` its pose.
    pattern : (camera.height, camera.width) float
        Projected image in [0, 1].
    intensity : float
    color : (3,) float
    """

    camera: Camera
    pattern: np.ndarray
    intensity: float = 1.0
    color: np.ndarray = field(default_factory=lambda: np.ones(3))

    def __post_init__(self):
        if not isinstance(self.camera, Camera):
            raise ValueError(f"camera: expected an acquire.camera.Camera, got "
                             f"{type(self.camera).__name__}")
        self.pattern = check_array(self.pattern, "pattern",
                                   shape=(self.camera.height, self.camera.width))
        self.intensity = check_positive(self.intensity, "intensity", allow_zero=True)
        self.color = check_array(self.color, "color", shape=(3,))

    def with_pattern(self, pattern: np.ndarray) -> PatternProjector:
        """The same projector showing another image."""
        return PatternProjector(self.camera, pattern, self.intensity, self.color)

    def footprint(self, points: np.ndarray, normals: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Where points fall in the projector image and how much a white pixel lights them.

        Returns
        -------
        pixels : (n, 2) float64   projector pixels (NaN behind the projector)
        factor : (n,) float64     ``intensity * cos / r^2`` (0 facing away)

        ``irradiance = sample_bilinear(pattern, pixels) * factor * color``: renderers of
        many patterns compute the footprint once.
        """
        px, z = self.camera.project(points)
        px = np.where(z[:, None] > 1e-9, px, np.nan)
        d = self.camera.center - points
        r2 = np.einsum("ij,ij->i", d, d)
        cos = np.einsum("ij,ij->i", d, normals) / np.sqrt(np.maximum(r2, 1e-300))
        return px, self.intensity * np.clip(cos, 0.0, None) / np.maximum(r2, 1e-12)

    def irradiance(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Unshadowed irradiance ``(n, 3)`` at ``points (n, 3)`` with unit ``normals (n, 3)``."""
        px, factor = self.footprint(points, normals)
        return (sample_bilinear(self.pattern, px) * factor)[:, None] * self.color

    def shadow_rays(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rays from the points to the projector centre (occluded if hit with t < 1)."""
        return self.camera.center - points, np.ones(len(points))
