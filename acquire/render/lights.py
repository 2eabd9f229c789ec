"""Lights for the ray-cast renderer.

Every light implements the same two-method protocol, so laser sheets and pattern
projectors plug into :func:`acquire.render.renderer.render` like lamps do:

``irradiance(points (n, 3), normals (n, 3)) -> (n, 3) float64``
    Unshadowed light arriving at surface points, cosine term included (normals
    are unit and face the viewer).
``shadow_rays(points (n, 3)) -> (directions (n, 3), max_t (n,))``
    Rays from the surface toward the light; the point is in shadow when the
    scene is hit with ``t < max_t``.

Units: a unit-intensity light falling head-on on a white Lambertian surface
gives radiance 1 (point lights: at 1 m; they fall off with the inverse square).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from core.validate import check_array, check_positive

__all__ = ["Light", "PointLight", "DirectionalLight"]

FAR = 1e6  # a directional light's shadow rays reach this far (m)


class Light(Protocol):  # pragma: no cover - a protocol
    def irradiance(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray: ...

    def shadow_rays(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass
class PointLight:
    """An isotropic point light at ``position`` (m) with inverse-square falloff."""

    position: np.ndarray
    intensity: float = 1.0
    color: np.ndarray = field(default_factory=lambda: np.ones(3))

    def __post_init__(self):
        self.position = check_array(self.position, "position", shape=(3,))
        self.intensity = check_positive(self.intensity, "intensity", allow_zero=True)
        self.color = check_array(self.color, "color", shape=(3,))

    def irradiance(self, points, normals):
        d = self.position - points
        r2 = np.einsum("ij,ij->i", d, d)
        cos = np.einsum("ij,ij->i", d, normals) / np.sqrt(np.maximum(r2, 1e-300))
        e = self.intensity * np.clip(cos, 0.0, None) / np.maximum(r2, 1e-12)
        return e[:, None] * self.color

    def shadow_rays(self, points):
        return self.position - points, np.ones(len(points))


@dataclass
class DirectionalLight:
    """A distant light travelling along ``direction`` (e.g. the sun)."""

    direction: np.ndarray
    intensity: float = 1.0
    color: np.ndarray = field(default_factory=lambda: np.ones(3))

    def __post_init__(self):
        d = check_array(self.direction, "direction", shape=(3,))
        n = np.linalg.norm(d)
        if n == 0:
            raise ValueError("direction: expected a non-zero vector, got (0, 0, 0)")
        self.direction = d / n
        self.intensity = check_positive(self.intensity, "intensity", allow_zero=True)
        self.color = check_array(self.color, "color", shape=(3,))

    def irradiance(self, points, normals):
        cos = -(normals @ self.direction)
        return (self.intensity * np.clip(cos, 0.0, None))[:, None] * self.color

    def shadow_rays(self, points):
        return np.broadcast_to(-self.direction, points.shape).copy(), np.full(len(points), FAR)
