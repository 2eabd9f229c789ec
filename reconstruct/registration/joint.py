"""Simultaneous alignment of many scans: one linearised least-squares step for all poses
at once over point-to-plane correspondences between every overlapping pair (multi-view
ICP: Neugebauer 1997; Pulli 1999, doi:10.1109/IM.1999.805346).

Poses are ``model_from_scan`` matrices (one per scan, the anchor held fixed). For a point
``p`` of scan i matched to ``q`` (normal ``n``) of scan j, the residual
``n' . (X_i p - X_j q)`` (``n'`` in the model frame) is linearised in left increments of
both poses; a Cauchy weight keeps outliers from pulling.

>>> import numpy as np
>>> from .oriented import Oriented

log = logging.getLogger(__name__)
>>> rng = np.random.default_rng(0)
>>> pts = rng.normal(size=(2000, 3)) * [1.0, 0.6, 0.3]
>>> nrm = rng.normal(size=(2000, 3)); nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
>>> a = Oriented(pts, nrm, nrm)
>>> true = [np.eye(4), np.eye(4)]
>>> guess = [np.eye(4), np.eye(4)]; guess[1][:3, 3] = [0.01, -0.02, 0.005]
>>> out = JointAlignment([a, a], [(0, 1)]).run(guess, thresholds=[0.1] * 10)
>>> bool(np.allclose(out[1], np.eye(4), atol=1e-6))
True
"""

from __future__ import annotations

import itertools
import logging

import numpy as np

from core.frames import transform_points

from .icp import rigid_step
from .oriented import Oriented

log = logging.getLogger(__name__)

__all__ = ["JointAlignment"]


class JointAlignment:
    """Multi-view ICP over ``pairs`` of ``views`` (each in its own frame).

    Parameters
    ----------
    views : list of Oriented
    pairs : list of (i, j)
        Scan pairs to match (both directions are used).
    anchor : int
        The scan whose pose stays fixed.
    min_normal_dot : float
        Matches whose normals differ by more than this cosine are dropped.
    """

    def __init__(self, views: list[Oriented], pairs, *, anchor: int = 0,
                 min_normal_dot: float = 0.5):
        from scipy.spatial import cKDTree

        self.views = views
        self.pairs = sorted({(min(i, j), max(i, j)) for i, j in pairs if i != j})
        self.anchor = anchor
        self.min_dot = min_normal_dot
        self.trees = [cKDTree(v.points) for v in views]
        self.last: dict = {}

    def _matches(self, poses, i, j, threshold):
        """Correspondences of i's points to j's surface: model-frame P, Q, N."""
        rel = np.linalg.inv(poses[j]) @ poses[i]
        vi, vj = self.views[i], self.views[j]
        p_in_j = transform_points(rel, vi.points)
        d, k = self.trees[j].query(p_in_j, distance_upper_bound=threshold)
        ok = np.isfinite(d)
        ok[ok] = np.sum((vi.normals[ok] @ rel[:3, :3].T) * vj.normals[k[ok]], axis=1) \
            > self.min_dot
        src = np.flatnonzero(ok)
        conf = vi.weights[ok] * vj.weights[k[ok]]
        Xj = poses[j]
        P = transform_points(Xj, p_in_j[ok])
        Q = transform_points(Xj, vj.points[k[ok]])
        N = vj.normals[k[ok]] @ Xj[:3, :3].T
        return src, P, Q, N, conf

    def step(self, poses: list[np.ndarray], threshold: float) -> list[np.ndarray]:
        """One joint Gauss-Newton step with matches within ``threshold``; also fills
        ``self.last`` with per-scan residual sums and matched-sample masks."""
        n = len(poses)
        H = np.zeros((6 * n, 6 * n))
        g = np.zeros(6 * n)
        sq = np.zeros(n)
        cnt = np.zeros(n)
        matched = [np.zeros(len(v), bool) for v in self.views]
        pair_rms = {}
        sigma = 0.5 * threshold
        for i, j in self.pairs:
            for a, b in ((i, j), (j, i)):
                src, P, Q, N, conf = self._matches(poses, a, b, threshold)
                if len(src) < 6:
                    continue
                matched[a][src] = True
                r = np.einsum("ij,ij->i", N, P - Q)
                w = conf / (1.0 + (r / sigma) ** 2)
                sq[a] += np.sum(r ** 2)
                cnt[a] += len(r)
                pair_rms[(a, b)] = float(np.sqrt(np.mean(r ** 2)))
                Ja = np.hstack([np.cross(P, N), N])
                Jb = -np.hstack([np.cross(Q, N), N])
                for (u, Ju), (v, Jv) in itertools.product(((a, Ja), (b, Jb)), repeat=2):
                    H[6 * u:6 * u + 6, 6 * v:6 * v + 6] += (Ju * w[:, None]).T @ Jv
                for u, Ju in ((a, Ja), (b, Jb)):
                    g[6 * u:6 * u + 6] += (Ju * w[:, None]).T @ r
        free = np.array([k for k in range(n) if k != self.anchor], dtype=np.int64)
        if len(free) == 0:
            self.last = {"sq": sq, "count": cnt, "matched": matched, "pair_rms": pair_rms,
                         "step": 0.0}
            return list(poses)
        idx = (6 * free[:, None] + np.arange(6)).ravel()
        Hf = H[np.ix_(idx, idx)]
        Hf += 1e-9 * np.trace(Hf) / max(1, len(idx)) * np.eye(len(idx)) + 1e-12 * np.eye(len(idx))
        x = np.zeros(6 * n)
        x[idx] = -np.linalg.solve(Hf, g[idx])
        self.last = {"sq": sq, "count": cnt, "matched": matched, "pair_rms": pair_rms,
                     "step": float(np.max(np.abs(x))) if len(x) else 0.0}
        return [rigid_step(x[6 * k:6 * k + 6]) @ poses[k] for k in range(n)]

    def run(self, poses: list[np.ndarray], *, thresholds, tol: float = 1e-7
            ) -> list[np.ndarray]:
        """Steps at each threshold of ``thresholds`` in turn (stopping early, once at the
        last threshold, when the largest increment falls under ``tol``: radians and
        metres alike)."""
        poses = [np.array(p, dtype=np.float64) for p in poses]
        thresholds = list(thresholds)
        for k, th in enumerate(thresholds):
            poses = self.step(poses, th)
            log.debug("joint step %d at %.3g: largest increment %.3g", k, th, self.last["step"])
            if th == thresholds[-1] and self.last["step"] < tol:
                break
        return poses

