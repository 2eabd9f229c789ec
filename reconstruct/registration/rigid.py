"""Rigid registration of a scan to a reference, from any starting frame: deterministic.

A laser scan comes out in its turntable's frame, an SfM model in its own, a handheld
scan in the scanner's. To score such a scan against a reference, :func:`register`
finds ``reference_from_scan``:

1. **Coarse** (``method="global"``): both sides are thinned on a voxel grid of 1/40 of
   the smaller of the two diagonals and described by FPFH features (:mod:`.features`:
   Rusu et al. 2009, Open3D's implementation). Matches in feature space feed the room's
   seeded RANSAC (:func:`.features.ransac_rigid`). The 24 rotations that map the scan's
   principal axes onto the reference's are candidates too, for shapes whose features are
   poor (smooth, symmetric). Each candidate is refined by point-to-point ICP at two
   voxels; the one that then puts most scan points within half a voxel of the reference
   wins.
2. **Fine**: ICP (:func:`.icp.icp`, point-to-plane with the reference's normals) at the
   given threshold.

Same inputs and seed, same transform, to the last bit.

>>> import numpy as np
>>> from core.frames import rotation_about, transform_points
>>> rng = np.random.default_rng(0)
>>> pts = rng.normal(size=(2000, 3)) * [0.05, 0.03, 0.01]
>>> moved = pts @ rotation_about([0, 0, 1], 2.0)[:3, :3].T + [0.3, -0.1, 0.05]
>>> reg = register(moved, pts, method="global", rng=np.random.default_rng(1))
>>> bool(np.allclose(transform_points(reg.transform, moved), pts, atol=1e-6))
True
"""

from __future__ import annotations

import itertools
import logging

import numpy as np

from core.sampling import voxel_thin
from core.validate import check_array, check_choice, check_positive

from .features import fpfh, match_features, ransac_rigid
from .icp import Registration, icp, score

log = logging.getLogger(__name__)

__all__ = ["register", "ALIGN_METHODS", "LOW_FITNESS"]

#: ``scanamp evaluate --align`` choices
ALIGN_METHODS = ("none", "icp", "global")
#: below this fraction of scan points within the ICP threshold, the alignment is suspect
LOW_FITNESS = 0.5

_VOXEL_FRACTION = 1.0 / 40.0
_RANSAC_ITERATIONS = 4000
#: hypotheses of the RANSAC that go on to the ICP judge: the right pose of a partial scan
#: need not have the most feature inliers, so more than a few
_RANSAC_KEEP = 20
#: ICP here runs to convergence: one scan, aligned once, its figures reported
_CONVERGED = {"rotation_tol": 1e-10, "translation_tol": 1e-9}
_MAX_POINTS = 60000


def _features(points: np.ndarray, voxel: float) -> np.ndarray:
    """FPFH of thinned points, with normals estimated here (pointing away from a far point
    for a deterministic sign)."""
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points)))
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2.5 * voxel, max_nn=30))
    pc.orient_normals_towards_camera_location(points.mean(axis=0) + 1e6)
    return fpfh(points, np.asarray(pc.normals), 5.0 * voxel)


def _principal_axes(src: np.ndarray, dst: np.ndarray) -> list[np.ndarray]:
    def frame(p):
        c = p.mean(axis=0)
        _, vec = np.linalg.eigh(np.cov((p - c).T))
        return c, vec

    cs, es = frame(src)
    cd, ed = frame(dst)
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[list(perm), [0, 1, 2]] = signs
            r = ed @ m @ es.T
            if np.linalg.det(r) < 0:
                continue
            t = np.eye(4)
            t[:3, :3], t[:3, 3] = r, cd - r @ cs
            out.append(t)
    return out


def register(scan: np.ndarray, reference: np.ndarray, *, method: str = "global",
             reference_normals: np.ndarray | None = None, threshold: float | None = None,
             rng: np.random.Generator | None = None) -> Registration:
    """Find ``reference_from_scan`` (see the module docstring).

    Parameters
    ----------
    scan, reference : (n, 3) float
        Points (e.g. surface samples) of the scan and of the reference.
    method : {"icp", "global"}
        ``"icp"`` starts from the identity; ``"global"`` finds a coarse alignment first.
    reference_normals : (n, 3) float, optional
        Enables point-to-plane ICP.
    threshold : float, optional
        Final ICP correspondence distance in metres; default 1 % of the reference's
        bounding-box diagonal.
    rng : numpy.random.Generator, optional
        For RANSAC and subsampling; default ``default_rng(0)``.
    """
    from scipy.spatial import cKDTree

    check_choice(method, "method", ("icp", "global"))
    src = check_array(scan, "scan", shape=(None, 3), min_rows=3)
    dst = check_array(reference, "reference", shape=(None, 3), min_rows=3)
    rng = np.random.default_rng(0) if rng is None else rng
    diag = float(np.linalg.norm(dst.max(axis=0) - dst.min(axis=0)))
    if diag <= 0:
        raise ValueError("reference: all points coincide")
    threshold = 0.01 * diag if threshold is None else check_positive(threshold, "threshold")
    if len(src) > _MAX_POINTS:
        src = src[np.sort(rng.choice(len(src), _MAX_POINTS, replace=False))]
    details: dict = {}
    init = np.eye(4)
    if method == "global":
        # the voxel follows the smaller of the two (a partial scan of one object in a
        # scene): features must resolve the scan's shape
        sdiag = float(np.linalg.norm(src.max(axis=0) - src.min(axis=0)))
        voxel = _VOXEL_FRACTION * min(diag, sdiag if sdiag > 0 else diag)
        s, d = src[voxel_thin(src, voxel)], dst[voxel_thin(dst, voxel)]
        matches = match_features(_features(s, voxel), _features(d, voxel))
        candidates = ransac_rigid(s, d, matches, inlier=1.5 * voxel, rng=rng,
                                  iterations=_RANSAC_ITERATIONS, keep=_RANSAC_KEEP,
                                  min_edge=voxel)
        n_ransac = len(candidates)
        candidates += _principal_axes(s, d)
        tree = cKDTree(d)
        # every candidate is refined by ICP at two voxels, then judged at half a voxel,
        # so near-symmetric shapes are told apart by their detail
        refined = [icp(s, d, t, 2.0 * voxel, tree=tree, iterations=20,
                       **_CONVERGED).transform for t in candidates]
        scores = [score(t, s, tree, 0.5 * voxel)[0] for t in refined]
        k = int(np.argmax(scores))
        init = refined[k]
        details["coarse"] = {"source": "fpfh_ransac" if k < n_ransac else "principal_axes",
                             "fitness": scores[k], "voxel_m": voxel,
                             "candidates": len(candidates)}
    fine = icp(src, dst, init, threshold, target_normals=reference_normals, iterations=40,
               **_CONVERGED)
    t, fitness, rmse = fine.transform, fine.fitness, fine.inlier_rmse
    if fitness == 0:
        log.warning("alignment found no correspondences within %.4g m; scoring unaligned",
                    threshold)
        return Registration(np.eye(4), 0.0, float("nan"), threshold, method, details)
    if fitness < LOW_FITNESS:
        log.debug("alignment is doubtful: only %.0f%% of the scan lies within %.3g m of the "
                    "reference after %s alignment; the scores below may mean nothing",
                    100 * fitness, threshold, method)
    return Registration(t, fitness, rmse, threshold, method, details)
