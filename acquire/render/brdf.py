"""Reflectance models: Lambertian and GGX microfacet (conductor or dielectric coating).

Directions are unit vectors pointing away from the surface: ``wi`` toward the light,
``wo`` toward the viewer, ``n`` the shading normal. Every function returns the BRDF
``f(wi, wo)`` in 1/sr, ``(k, 3)`` per colour channel, zero below the horizon; the
radiance reflected from irradiance ``E`` arriving along ``wi`` is ``f * E``.

- :func:`lambert`: ``albedo / pi``.
- :func:`ggx`: Cook-Torrance with the GGX (Trowbridge-Reitz) normal distribution
  ``D(h) = a^2 / (pi ((n.h)^2 (a^2 - 1) + 1)^2)``, ``a = roughness^2``, the
  height-correlated Smith masking-shadowing term and Schlick's Fresnel
  ``F = F0 + (1 - F0)(1 - wo.h)^5``:
  ``f = D G F / (4 (n.wi)(n.wo))``. A *conductor* (metal) has ``F0`` = its colour and no
  diffuse part; a *dielectric* (plastic, varnish) has ``F0 = ((ior - 1)/(ior + 1))^2``
  and a Lambertian base weighted by ``1 - F`` of the view and light directions, so the
  two together do not create energy.

References: B. Walter et al., "Microfacet models for refraction through rough surfaces",
EGSR 2007 (GGX); E. Heitz, "Understanding the masking-shadowing function in
microfacet-based BRDFs", JCGT 3(2), 2014 (height-correlated Smith); C. Schlick, "An
inexpensive BRDF model for physically-based rendering", CGF 13(3), 1994.

>>> import numpy as np
>>> n = np.array([[0.0, 0.0, 1.0]])
>>> w = np.array([[0.0, 0.6, 0.8]]); r = w * [1, -1, 1]       # mirror pair
>>> bool(ggx(w, r, n, roughness=0.2, f0=0.9)[0, 0] > ggx(w, w, n, roughness=0.2, f0=0.9)[0, 0])
True
"""

from __future__ import annotations

import numpy as np

__all__ = ["lambert", "ggx", "ggx_d", "smith_g", "schlick", "dielectric_f0", "BRDFS",
           "sample_mixture", "mixture_pdf"]

BRDFS = ("lambert", "conductor", "dielectric", "subsurface", "translucent")


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def lambert(wi: np.ndarray, wo: np.ndarray, n: np.ndarray, albedo) -> np.ndarray:
    """``albedo / pi`` where both directions are above the surface, else 0."""
    up = (_dot(wi, n) > 0) & (_dot(wo, n) > 0)
    return np.where(up[:, None], np.broadcast_to(np.asarray(albedo, float), (len(n), 3))
                    / np.pi, 0.0)


def ggx_d(cos_h: np.ndarray, alpha: float) -> np.ndarray:
    """GGX normal distribution at ``cos_h = n.h`` (normalised: int D (n.h) dw_h = 1)."""
    a2 = alpha * alpha
    c2 = np.clip(cos_h, 0.0, 1.0) ** 2
    return np.where(cos_h > 0, a2 / (np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2), 0.0)


def _lambda(cos_t: np.ndarray, alpha: float) -> np.ndarray:
    c2 = np.clip(cos_t, 1e-12, 1.0) ** 2
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * (1.0 - c2) / c2) - 1.0)


def smith_g(cos_i: np.ndarray, cos_o: np.ndarray, alpha: float) -> np.ndarray:
    """Height-correlated Smith masking-shadowing ``1 / (1 + L(wi) + L(wo))``."""
    return 1.0 / (1.0 + _lambda(cos_i, alpha) + _lambda(cos_o, alpha))


def schlick(f0, cos_d: np.ndarray) -> np.ndarray:
    """Schlick's Fresnel ``(k, 3)`` at ``cos_d`` (the angle between ``wo`` and ``h``)."""
    f0 = np.broadcast_to(np.asarray(f0, float), (len(cos_d), 3))
    return f0 + (1.0 - f0) * (1.0 - np.clip(cos_d, 0.0, 1.0))[:, None] ** 5


def dielectric_f0(ior: float) -> float:
    """Normal-incidence reflectance of a dielectric of refractive index ``ior`` (in air)."""
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def ggx(wi: np.ndarray, wo: np.ndarray, n: np.ndarray, *, roughness: float, f0,
        diffuse=None) -> np.ndarray:
    """GGX microfacet BRDF ``(k, 3)``: the specular lobe, plus with ``diffuse`` (an
    albedo) a Lambertian base under a dielectric coating, weighted by the light that the
    coating transmits on the way in and out (``(1 - F(wi)) (1 - F(wo))``)."""
    alpha = max(float(roughness), 1e-3) ** 2
    ci, co = _dot(wi, n), _dot(wo, n)
    up = (ci > 0) & (co > 0)
    h = wi + wo
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
    ch = _dot(n, h)
    spec = (ggx_d(ch, alpha) * smith_g(ci, co, alpha))[:, None] * schlick(f0, _dot(wo, h))
    spec /= np.maximum(4.0 * ci * co, 1e-12)[:, None]
    out = spec
    if diffuse is not None:
        t = (1.0 - schlick(f0, ci)) * (1.0 - schlick(f0, co))
        out = out + t * np.asarray(diffuse, float) / np.pi
    return np.where(up[:, None], out, 0.0)


def _basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents ``(t, b)`` completing each normal of ``n (k, 3)`` to a frame."""
    a = np.where(np.abs(n[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(n, a)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(n, t)


def mixture_pdf(wi: np.ndarray, wo: np.ndarray, n: np.ndarray, *, roughness: float,
                p_spec: float) -> np.ndarray:
    """Density (1/sr) of :func:`sample_mixture` at ``wi``: ``p_spec`` times the GGX
    normal sampling's ``D(h) (n.h) / (4 |wo.h|)`` plus ``1 - p_spec`` times the cosine
    density ``max(n.wi, 0) / pi``."""
    alpha = max(float(roughness), 1e-3) ** 2
    ci = _dot(wi, n)
    pdf = (1.0 - p_spec) * np.clip(ci, 0.0, None) / np.pi
    if p_spec > 0:
        h = wi + wo
        h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
        ch = _dot(n, h)
        pdf = pdf + p_spec * ggx_d(ch, alpha) * np.clip(ch, 0.0, None) / np.maximum(
            4.0 * np.abs(_dot(wo, h)), 1e-12)
    return pdf


def sample_mixture(wo: np.ndarray, n: np.ndarray, u: np.ndarray, *, roughness: float,
                   p_spec: float) -> tuple[np.ndarray, np.ndarray]:
    """Importance-sample light directions ``wi (k, 3)`` for views ``wo`` at normals ``n``
    with uniform numbers ``u (k, 3)``: with probability ``p_spec`` by the GGX normal
    distribution (the half vector drawn from ``D(h) (n.h)``, ``wi`` its mirror of
    ``wo``), else cosine-weighted; returns ``(wi, pdf)`` with the mixture's density
    (one-sample multiple importance sampling, the balance heuristic). Directions below
    the surface have their density but reflect nothing (the BRDFs are 0 there)."""
    alpha = max(float(roughness), 1e-3) ** 2
    t, b = _basis(n)
    spec = u[:, 2] < p_spec
    # cosine-weighted (Malley)
    r, phi = np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.clip(1.0 - u[:, 0], 0,
                                                                       None))], 1)
    # GGX half vectors
    ch = np.sqrt((1.0 - u[:, 0]) / (1.0 + (alpha * alpha - 1.0) * u[:, 0]))
    sh = np.sqrt(np.clip(1.0 - ch * ch, 0.0, None))
    hl = np.stack([sh * np.cos(phi), sh * np.sin(phi), ch], 1)
    to_world = np.stack([t, b, n], axis=2)                  # columns t, b, n
    d = np.einsum("kij,kj->ki", to_world, local)
    h = np.einsum("kij,kj->ki", to_world, hl)
    mirror = 2.0 * _dot(wo, h)[:, None] * h - wo
    wi = np.where(spec[:, None], mirror, d)
    return wi, mixture_pdf(wi, wo, n, roughness=roughness, p_spec=p_spec)
