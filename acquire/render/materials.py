"""Surface materials: constant albedo, solid procedural textures, UV image textures, and
a reflectance model (:mod:`acquire.render.brdf`): Lambertian, a GGX conductor (metal: the albedo
is its normal-incidence reflectance) or a GGX-coated dielectric (plastic, varnish: the
albedo is the diffuse base under a clear coat of refractive index ``ior``).

Solid textures are evaluated at points in the OBJECT frame, so they move with the
object (a turntable scan sees the same texture at every angle).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acquire.render.brdf import BRDFS, dielectric_f0, ggx
from acquire.render.subsurface import DEFAULT_ANISOTROPY
from core.validate import check_array, check_choice, check_positive, check_range
from procgen.noise import SOLID_TEXTURES, fbm

__all__ = ["Material", "MATERIAL_KINDS", "BRDFS", "MATERIAL_PRESETS"]

MATERIAL_KINDS = ("constant", "solid", "image")

# Named reflectances (fields of Material besides its colour and texture), the rows of a
# material study: matte, a plastic's glossy coat at three roughnesses, polished metal,
# and translucent materials from marble-like to wax-like mean free paths.
MATERIAL_PRESETS = {
    "matte": {"brdf": "lambert"},
    "glossy-0.1": {"brdf": "dielectric", "roughness": 0.1},
    "glossy-0.3": {"brdf": "dielectric", "roughness": 0.3},
    "glossy-0.6": {"brdf": "dielectric", "roughness": 0.6},
    "metal": {"brdf": "conductor", "roughness": 0.15},
    "subsurface-0.3mm": {"brdf": "subsurface", "mfp": 0.3e-3},
    "subsurface-1mm": {"brdf": "subsurface", "mfp": 1e-3},
    "subsurface-3mm": {"brdf": "subsurface", "mfp": 3e-3},
}


FBM_OCTAVES = 5  # octaves of the 'fbm' solid texture


def _fbm_texture(points: np.ndarray, *, scale: float, seed: int | None,
                 octaves: int = FBM_OCTAVES) -> np.ndarray:
    """Multi-octave Perlin value in about [-1, 1], rich in features for matching."""
    p = points * scale
    norm = 2.0 - 0.5 ** (octaves - 1)  # sum of the octave amplitudes (gain 0.5)
    return fbm(p[:, 0], p[:, 1], p[:, 2], octaves=octaves, seed=seed) / norm * 1.8


def solid_texture_names() -> tuple[str, ...]:
    """'fbm' (albedo modulated by fBm) and the noise family's solid textures."""
    return tuple(sorted({"fbm", *SOLID_TEXTURES}))


@dataclass(eq=False)
class Material:
    """A material: where its colour comes from, and how it reflects.

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
    brdf : {'lambert', 'conductor', 'dielectric', 'subsurface'}
        The reflectance model (:mod:`acquire.render.brdf`); ``subsurface`` is a translucent
        material (marble, wax, skin) whose albedo is its diffuse reflectance and whose
        light spreads under the surface by the dipole profile (:mod:`acquire.render.subsurface`):
        a laser stripe widens and shifts; the share scattered only once leaves where it
        entered, brighter toward grazing angles (``anisotropy``); under broad light it
        reflects its albedo;
        ``translucent`` is a thin sheet (a leaf, paper, a lampshade) that reflects
        ``1 - transmission`` of its albedo diffusely and lets ``transmission`` of it
        through, diffusely, to the other side.
    roughness : float
        GGX roughness in (0, 1] (alpha = roughness^2): 0.05 a polished part, 1 matte.
    ior : float
        Refractive index of a dielectric's coat or of a translucent material (1.5:
        plastics, varnish; marble 1.49).
    transmission : float
        Share of a thin translucent material's albedo sent through to the other side.
    mfp : float
        Mean free path of a subsurface material, metres (1 / reduced extinction; marble
        about 0.4 mm, skin 1 mm, wax several mm).
    anisotropy : float
        Henyey-Greenstein mean cosine ``g`` of a subsurface material's scattering, in
        (-1, 1): 0 isotropic, toward 1 forward. It sets how much light is scattered once
        and straight back (the local, angular part of the reflection,
        :func:`acquire.render.subsurface.single_scattering`); the diffusion depends only on the
        reduced mean free path.
    """

    kind: str = "constant"
    albedo: np.ndarray = field(default_factory=lambda: np.array([0.7, 0.7, 0.7]))
    texture: str = "fbm"
    scale: float = 40.0
    contrast: float = 0.8
    seed: int | None = None
    image: np.ndarray | None = None
    brdf: str = "lambert"
    roughness: float = 0.5
    ior: float = 1.5
    mfp: float = 1e-3
    transmission: float = 0.5
    anisotropy: float = DEFAULT_ANISOTROPY

    def __post_init__(self):
        check_choice(self.kind, "kind", MATERIAL_KINDS)
        check_choice(self.brdf, "brdf", BRDFS)
        self.roughness = check_range(self.roughness, "roughness", 0.0, 1.0, lo_open=True)
        self.ior = check_range(self.ior, "ior", 1.0, 4.0, lo_open=True)
        self.mfp = check_range(self.mfp, "mfp", 0.0, 1.0, lo_open=True)
        self.transmission = check_range(self.transmission, "transmission", 0.0, 1.0)
        self.anisotropy = check_range(self.anisotropy, "anisotropy", -1.0, 1.0,
                                      lo_open=True, hi_open=True)
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


    def reflectance(self, wi: np.ndarray, wo: np.ndarray, n: np.ndarray,
                    albedo: np.ndarray) -> np.ndarray:
        """``pi`` times the BRDF ``(k, 3)`` for light from ``wi`` seen from ``wo`` at
        normals ``n`` (the renderer's convention: a Lambertian surface reflects its
        ``albedo`` times the irradiance)."""
        if self.brdf == "translucent":   # reflected on the lit side, else sent through
            same = (np.einsum("ij,ij->i", wi, n) > 0) == (np.einsum("ij,ij->i", wo, n) > 0)
            t = self.transmission
            return albedo * np.where(same, 1.0 - t, t)[:, None]
        if self.brdf in ("lambert", "subsurface"):   # diffusion under broad light
            up = (np.einsum("ij,ij->i", wi, n) > 0) & (np.einsum("ij,ij->i", wo, n) > 0)
            return np.where(up[:, None], albedo, 0.0)
        if self.brdf == "conductor":
            return np.pi * ggx(wi, wo, n, roughness=self.roughness, f0=albedo)
        return np.pi * ggx(wi, wo, n, roughness=self.roughness, f0=dielectric_f0(self.ior),
                           diffuse=albedo)


    def dipole(self, channel: int):
        """The :class:`acquire.render.subsurface.Dipole` of a subsurface material in one colour
        channel (its base albedo there)."""
        from acquire.render.subsurface import Dipole

        return Dipole(max(float(self.albedo[channel]), 1e-3), float(self.mfp),
                      float(self.ior), float(self.anisotropy))

    def subsurface_shares(self) -> tuple[np.ndarray, np.ndarray]:
        """Of a subsurface material's albedo, per colour channel: the share carried by the
        diffusion (spread under the surface) and the share scattered once (local), under
        broad light; they sum to 1."""
        d = [self.dipole(c) for c in range(3)]
        single = np.array([x.single / x.albedo for x in d])
        return np.array([x.diffusion / x.albedo for x in d]), single

    def diffusion_weight(self, mu: np.ndarray) -> np.ndarray:
        """``(k, 3)``: the angular weight of a subsurface material's diffusion at the
        entry or exit cosines ``mu``, per colour channel, over its cosine-weighted mean
        (:meth:`acquire.render.subsurface.Dipole.diffusion_entry` over
        :attr:`~acquire.render.subsurface.Dipole.entry_mean`): 1 at every angle unless the
        single scattering of a near grazing beam leaves the diffusion less."""
        mu = np.asarray(mu, np.float64)
        d = [self.dipole(c) for c in range(3)]
        return np.stack([x.diffusion_entry(mu) / x.entry_mean for x in d], axis=-1)

    def single_scattering(self, wi: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
        """``(k, 3)``: the radiance that a subsurface material scatters once, per unit
        irradiance from ``wi`` and per unit albedo, seen from ``wo`` at normals ``n``
        (:func:`acquire.render.subsurface.single_scattering` times the single-scattering albedo
        over the base albedo): times a hit's albedo and its irradiance, it is that hit's
        single-scattered radiance; under broad light it averages to the single share of
        :meth:`subsurface_shares`."""
        from acquire.render.subsurface import single_scattering

        f = single_scattering(wi, wo, n, g=float(self.anisotropy), eta=float(self.ior))
        k = np.array([d.single_albedo / d.albedo for d in map(self.dipole, range(3))])
        return f[:, None] * k[None, :]


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
