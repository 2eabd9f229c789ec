"""The beam's footprint, sampled by sub-rays in its divergence cone.

A pulse's beam is a cone of full angle ``divergence`` (at the 1/e^2 points of its
Gaussian profile). It is sampled by ``n x n`` sub-rays (``n`` odd): one along the axis and
``(n - 1) / 2`` rings of ``8 k`` rays at ``k / K`` of the cone's half-angle, the outer
ring on the cone itself. Each sub-ray carries the beam energy of its annulus under the
Gaussian profile (the weights sum to 1). The footprint is wherever the cone meets the
world: a circle of diameter ``divergence x range`` at normal incidence, an ellipse
stretched by ``1 / cos(incidence)`` on a tilted surface, split between surfaces at an
edge. Nothing is assumed about its shape: it follows from casting the sub-rays.

>>> offs, w = subray_pattern(5)
>>> offs.shape, round(float(w.sum()), 12)
((25, 2), 1.0)
>>> float(np.hypot(*offs.T).max())
1.0
"""

from __future__ import annotations

import numpy as np

from core.validate import InputError

__all__ = ["subray_pattern", "subray_directions", "orthonormal_frames", "pack_rays"]


def subray_pattern(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Sub-ray offsets and weights of an ``n x n`` footprint (``n`` odd).

    Returns
    -------
    offsets : (n*n, 2) float64
        In units of the cone's half-angle (the outer ring at radius 1).
    weights : (n*n,) float64
        Share of the pulse energy, summing to 1 (Gaussian profile, 1/e^2 at radius 1).
    """
    n = int(n)
    if n < 1 or n % 2 == 0:
        raise InputError(f"expected an odd number of sub-rays per side (1, 3, 5...), got {n}",
                         field="footprint_samples")
    K = (n - 1) // 2
    offs = [np.zeros((1, 2))]
    weights = [_annulus(0.0, 0.5 / K if K else 1.0)]
    for k in range(1, K + 1):
        m = 8 * k
        phi = 2 * np.pi * (np.arange(m) + 0.5 * (k % 2)) / m
        r = k / K
        offs.append(np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1))
        weights.append(np.full(m, _annulus((k - 0.5) / K, min((k + 0.5) / K, 1.0)) / m))
    w = np.concatenate([np.atleast_1d(x) for x in weights])
    return np.vstack(offs), w / w.sum()


def _annulus(r0: float, r1: float) -> float:
    """Energy of a Gaussian beam ``exp(-2 r^2)`` between radii ``r0`` and ``r1``."""
    return float(np.exp(-2 * r0 ** 2) - np.exp(-2 * r1 ** 2))


def orthonormal_frames(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``(n, 3)`` each, orthogonal to the unit directions ``d (n, 3)``
    and to each other (a right-handed frame ``e1, e2, d``)."""
    a = np.where(np.abs(d[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(a, d)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(d, e1)


def subray_directions(d: np.ndarray, divergence_rad: float,
                      offsets: np.ndarray) -> np.ndarray:
    """Sub-ray unit directions ``(n, s, 3)`` about beam axes ``d (n, 3)``.

    ``offsets (s, 2)`` from :func:`subray_pattern`, scaled by the half-angle
    ``divergence_rad / 2``: a sub-ray at offset radius 1 makes that angle with the axis.
    """
    half = 0.5 * float(divergence_rad)
    e1, e2 = orthonormal_frames(d)
    r = np.hypot(offsets[:, 0], offsets[:, 1])
    ang = r * half
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.where(r > 0, offsets[:, 0] / np.maximum(r, 1e-300), 0.0)
        s = np.where(r > 0, offsets[:, 1] / np.maximum(r, 1e-300), 0.0)
    sa, ca = np.sin(ang), np.cos(ang)
    out = (d[:, None, :] * ca[None, :, None]
           + e1[:, None, :] * (sa * c)[None, :, None]
           + e2[:, None, :] * (sa * s)[None, :, None])
    return out


def pack_rays(origins: np.ndarray, d: np.ndarray, divergence_rad: float,
              offsets: np.ndarray) -> np.ndarray:
    """Embree's rays ``(n*s, 6) float32`` (origin, direction) of the sub-rays about beam
    axes ``d (n, 3)`` from ``origins (n, 3)``, pulse-major: what :func:`subray_directions`
    gives, packed by a compiled kernel without the (n, s, 3) intermediates."""
    from acquire.lidar import _kernels

    o = np.ascontiguousarray(origins, np.float64)
    d = np.ascontiguousarray(d, np.float64)
    rays = np.empty((len(d) * len(offsets), 6), np.float32)
    _kernels.pack_subrays(o, d, np.ascontiguousarray(offsets, np.float64),
                          0.5 * float(divergence_rad), rays)
    return rays
