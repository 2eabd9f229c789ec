"""Surface materials: constant albedo, solid procedural textures, UV image textures.

Solid textures are evaluated at points in the OBJECT frame, so they move with the
object (a turntable scan sees the same texture at every angle).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.validate import check_array, check_choice, check_positive
from procgen.noise import SOLID_TEXTURES, fbm

__all__ = ["Material", "MATERIAL_KINDS"]

MATERIAL_KINDS = ("constant", "solid", "image")


def _fbm_texture(points: np.ndarray, *, scale: float, seed: int | None,
                 octaves: int = 5) -> np.ndarray:
    """Multi-octave Perlin value in about [-1, 1], rich in features for matching."""
    p = points * scale
    norm = 2.0 - 0.5 ** (octaves - 1)  # sum of the octave amplitudes (gain 0.5)
    return fbm(p[:, 0], p[:, 1], p[:, 2], octaves=octaves, seed=seed) / norm * 1.8


def solid_texture_names() -> tuple[str, ...]:
    """'fbm' (albedo modulated by fBm) and the noise family's solid textures."""
    return tuple(sorted({"fbm", *SOLID_TEXTURES}))


@dataclass(eq=False)
class Material:
    """A Lambertian material.

    Parameters
    ----------
    kind : {'constant', 'solid', 'image'}
    albedo : (3,) float in [0, 1]
        Base colour (constant), or the colour modulated by the texture (solid 'fbm').
    texture : str
        Solid texture name: 'fbm' or any of ``procgen.noise.SOLID_TEXTURES``.
    scale : float
        Solid texture frequency in cycles per metre.
    contrast : float
        Strength of the 'fbm' modulation in [0, 1].
    seed : int or None
        Noise permutation of the solid texture.
    image : (h, w, 3) uint8, optional
        The 'image' texture, addressed by per-vertex UVs (u right, v down, in [0, 1]).
    """

    kind: str = "constant"
    albedo: np.ndarray = field(default_factory=lambda: np.array([0.7, 0.7, 0.7]))
    texture: str = "fbm"
    scale: float = 40.0
    contrast: float = 0.8
    seed: int | None = None
    image: np.ndarray | None = None

    def __post_init__(self):
        check_choice(self.kind, "kind", MATERIAL_KINDS)
        self.albedo = np.clip(check_array(self.albedo, "albedo", shape=(3,)), 0, 1)
        self.scale = check_positive(self.scale, "scale")
        if self.kind == "solid":
            check_choice(self.texture, "texture", solid_texture_names())
        if self.kind == "image":
            if self.image is None:
                raise ValueError("image: expected an (h, w, 3) image for an 'image' material")
            img = np.asarray(self.image)
            if img.ndim == 2:
                img = np.repeat(img[:, :, None], 3, axis=2)
            if img.ndim != 3 or img.shape[2] != 3:
                raise ValueError(f"image: expected shape (h, w, 3), got {img.shape}")
            self.image = img.astype(np.float64) / (255.0 if img.dtype == np.uint8 else 1.0)

    def albedo_at(self, points_object: np.ndarray, uvs: np.ndarray | None = None) -> np.ndarray:
        """Albedo ``(n, 3)`` at object-frame points (and UVs for image materials)."""
        n = len(points_object)
        if self.kind == "constant":
            return np.broadcast_to(self.albedo, (n, 3)).copy()
        if self.kind == "solid":
            if self.texture == "fbm":
                t = _fbm_texture(points_object, scale=self.scale, seed=self.seed)
                f = np.clip(0.5 + 0.5 * self.contrast * t, 0.02, 1.0)
                return f[:, None] * self.albedo
            return np.clip(SOLID_TEXTURES[self.texture](points_object, scale=self.scale,
                                                        seed=self.seed), 0.0, 1.0)
        if uvs is None:
            raise ValueError("uvs: an 'image' material needs per-vertex UVs on its mesh")
        return _bilinear(self.image, uvs)


def _bilinear(img: np.ndarray, uvs: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    x = np.clip(uvs[:, 0] * w - 0.5, 0, w - 1)
    y = np.clip(uvs[:, 1] * h - 0.5, 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(np.int64), w - 2 if w > 1 else 0)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 2 if h > 1 else 0)
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bot * fy
