"""ICP and the one result of every rigid registration in this room.

:func:`icp` refines ``target_from_source`` from a start by iterated closest points:
point-to-plane (linearised steps, Low 2004) when the target has normals, else
point-to-point (:func:`.features.kabsch`). It is ours rather than Open3D's: Open3D's
parallel reductions make the last bits of the result vary from run to run, and here the
same inputs give the same transform to the last bit.

:class:`Registration` is what a registration returns, as Open3D's ``RegistrationResult``:
the transform, the fitness (the fraction of source points within the threshold of the
target) and the RMS distance of those inliers.

>>> import numpy as np
>>> from core.frames import rotation_about, transform_points
>>> rng = np.random.default_rng(0)
>>> target = rng.normal(size=(500, 3))
>>> T = rotation_about([0, 0, 1], 0.05, center=[0.1, 0.0, 0.0])
>>> source = transform_points(np.linalg.inv(T), target)
>>> reg = icp(source, target, np.eye(4), 0.5)
>>> bool(np.allclose(reg.transform, T, atol=1e-9)), reg.fitness
(True, 1.0)

References
----------
K.-L. Low, "Linear least-squares optimization for point-to-plane ICP surface
registration", UNC TR04-004, 2004.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.frames import axis_angle_matrix, transform_points

from .features import kabsch

__all__ = ["Registration", "icp", "rigid_step", "score"]


@dataclass(frozen=True)
class Registration:
    """A rigid registration of a source onto a target.

    Attributes
    ----------
    transform : (4, 4) float64
        ``target_from_source``: maps source points into the target's frame.
    fitness : float
        Fraction of source points within ``threshold`` of the target after alignment.
    inlier_rmse : float
        RMS distance of those points (metres); NaN when there are none.
    threshold : float
        The correspondence distance (metres) the two figures above are measured at.
    method : str
        How it was found (``"icp"``, ``"global"``).
    details : dict
        What the method reports besides (the coarse stage of a global registration).
    """

    transform: np.ndarray
    fitness: float
    inlier_rmse: float
    threshold: float
    method: str = "icp"
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"method": self.method, "reference_from_scan": self.transform.tolist(),
                "fitness": self.fitness, "inlier_rmse_m": self.inlier_rmse,
                "threshold_m": self.threshold, **self.details}


def rigid_step(x: np.ndarray) -> np.ndarray:
    """The rigid 4x4 of a small step ``x = (rotation vector, translation)`` (6,)."""
    T = np.eye(4)
    angle = float(np.linalg.norm(x[:3]))
    if angle > 0:
        T[:3, :3] = axis_angle_matrix(x[:3] / angle, angle)
    T[:3, 3] = x[3:]
    return T


def score(T: np.ndarray, source: np.ndarray, tree, threshold: float) -> tuple[float, float]:
    """``(fitness, inlier_rmse)`` of ``source`` moved by ``T`` against the target indexed by
    ``tree`` (a ``scipy.spatial.cKDTree``), matches within ``threshold``."""
    d, _ = tree.query(transform_points(T, source), distance_upper_bound=threshold)
    ok = np.isfinite(d)
    rmse = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")
    return float(ok.mean()), rmse


def icp(source: np.ndarray, target: np.ndarray, init: np.ndarray, threshold: float, *,
        target_normals: np.ndarray | None = None, tree=None, iterations: int = 30,
        rotation_tol: float = 1e-7, translation_tol: float | None = None) -> Registration:
    """``target_from_source`` refined from ``init`` by ICP with matches within ``threshold``.

    Parameters
    ----------
    source : (n, 3) float64
    target : (m, 3) float64
    init : (4, 4) float64
        The starting ``target_from_source``.
    threshold : float
        Correspondence distance (metres).
    target_normals : (m, 3) float64, optional
        Unit normals of ``target``: point-to-plane steps; without them, point-to-point.
    tree : scipy.spatial.cKDTree, optional
        An index of ``target`` (built here when omitted).
    iterations : int
        At most this many steps; fewer than 6 matches stop it too.
    rotation_tol, translation_tol : float
        It stops after a step that turns less than ``rotation_tol`` radians and moves less
        than ``translation_tol`` metres (default ``1e-4 * threshold``).

    Returns
    -------
    Registration
        Fitness and inlier RMSE measured at ``threshold`` for the final transform.
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(target) if tree is None else tree
    translation_tol = 1e-4 * threshold if translation_tol is None else translation_tol
    T = np.array(init, dtype=np.float64)
    for _ in range(iterations):
        p = transform_points(T, source)
        d, j = tree.query(p, distance_upper_bound=threshold)
        ok = np.isfinite(d)
        if ok.sum() < 6:
            break
        p, q = p[ok], target[j[ok]]
        if target_normals is not None:
            n = target_normals[j[ok]]
            a = np.hstack([np.cross(p, n), n])
            x = np.linalg.solve(a.T @ a + 1e-12 * np.eye(6),
                                a.T @ np.einsum("ij,ij->i", q - p, n))
            step = rigid_step(x)
            turn = float(np.linalg.norm(x[:3]))
        else:
            step = kabsch(p, q)
            R = step[:3, :3]
            turn = float(np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0],
                                         R[1, 0] - R[0, 1]])) / 2.0
        T = step @ T
        if turn < rotation_tol and float(np.linalg.norm(step[:3, 3])) < translation_tol:
            break
    return Registration(T, *score(T, source, tree, threshold), threshold)
