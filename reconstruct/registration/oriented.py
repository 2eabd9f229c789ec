"""Oriented samples of a scan: points with normals and lines of sight, thinned on a voxel
grid in the scan's own canonical (principal-axis) frame.

The canonical frame makes everything downstream independent of how a scan happens to be
turned in the file: the principal axes of its points (signs fixed by the third moments)
are the same axes whatever rotation was applied to it, and so is the voxel grid that
thins it.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> p = rng.normal(size=(500, 3)) * [3.0, 2.0, 1.0] + rng.normal(size=(500, 3)) ** 2
>>> R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
>>> R *= np.linalg.det(R)
>>> a, b = canonical_frame(p), canonical_frame(p @ R.T)
>>> bool(np.allclose(transform_points(a, p), transform_points(b, p @ R.T), atol=1e-9))
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.frames import transform_points, unit
from core.validate import check_array

__all__ = ["Oriented", "canonical_frame", "thin_oriented", "apply_vectors"]


@dataclass(frozen=True)
class Oriented:
    """Oriented samples in one frame.

    Attributes
    ----------
    points : (n, 3) float64
    normals : (n, 3) float64
        Unit, facing the scanner.
    sight : (n, 3) float64
        Unit, from the point towards the scanner.
    confidence : (n,) float64 or None
        In [0, 1] (None: all 1).
    """

    points: np.ndarray
    normals: np.ndarray
    sight: np.ndarray
    confidence: np.ndarray | None = None

    def transformed(self, T: np.ndarray) -> Oriented:
        """The same samples in the frame ``T`` maps into (4x4 rigid)."""
        return Oriented(transform_points(T, self.points), apply_vectors(T, self.normals),
                        apply_vectors(T, self.sight), self.confidence)

    @property
    def weights(self) -> np.ndarray:
        """``confidence``, or ones."""
        return np.ones(len(self.points)) if self.confidence is None else self.confidence

    def __len__(self) -> int:
        return len(self.points)


def apply_vectors(T: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """The rotation of ``T`` applied to ``vectors (n, 3)``."""
    return vectors @ T[:3, :3].T


def canonical_frame(points: np.ndarray) -> np.ndarray:
    """``canon_from_scan`` (4x4): the centroid at the origin, the principal axes (largest
    first) along x, y, z, each axis's sign chosen so the third moment is positive.

    Parameters
    ----------
    points : (n, 3) float64, n >= 3
    """
    p = check_array(points, "points", shape=(None, 3), min_rows=3)
    c = p.mean(axis=0)
    q = p - c
    _, vec = np.linalg.eigh(q.T @ q)
    axes = vec[:, ::-1].T  # rows: principal axes, largest first
    proj = q @ axes.T
    skew = np.sum(proj ** 3, axis=0)
    signs = np.where(skew < 0, -1.0, 1.0)
    axes = axes * signs[:, None]
    if np.linalg.det(axes) < 0:  # keep a right-handed frame: the least-sure axis yields
        k = int(np.argmin(np.abs(skew) / (np.sum(np.abs(proj) ** 3, axis=0) + 1e-300)))
        axes[k] *= -1
    T = np.eye(4)
    T[:3, :3] = axes
    T[:3, 3] = -axes @ c
    return T


def thin_oriented(points: np.ndarray, normals: np.ndarray, sight: np.ndarray,
                  voxel: float, confidence: np.ndarray | None = None) -> Oriented:
    """Voxel centroids of ``points`` with their mean normal, line of sight and confidence.

    Parameters
    ----------
    points, normals, sight : (n, 3) float64
    confidence : (n,) float64, optional
    voxel : float
        Edge of the grid's cells (metres); the grid is anchored at the origin.

    Returns
    -------
    Oriented
        One sample per occupied cell, in the order of the cells' keys.
    """
    keys = np.floor(points / voxel).astype(np.int64)
    keys -= keys.min(axis=0)
    span = keys.max(axis=0) + 1
    lin = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    _, inv, count = np.unique(lin, return_inverse=True, return_counts=True)
    k = len(count)

    def mean(v):
        out = np.zeros((k, 3))
        np.add.at(out, inv, v)
        return out

    p = mean(points) / count[:, None]
    n = unit(mean(normals), tiny=1e-12, fill=np.nan)
    s = unit(mean(sight), tiny=1e-12, fill=np.nan)
    ok = np.all(np.isfinite(n), axis=1) & np.all(np.isfinite(s), axis=1)
    conf = None
    if confidence is not None:
        conf = np.bincount(inv, weights=np.asarray(confidence, float), minlength=k) / count
        conf = conf[ok]
    return Oriented(p[ok], n[ok], s[ok], conf)
