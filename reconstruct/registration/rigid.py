"""Rigid registration of a scan to a reference, from any starting frame: deterministic.

A laser scan comes out in its turntable's frame, an SfM model in its own, a handheld
scan in the scanner's. To score such a scan against a reference, :func:`register`
finds ``reference_from_scan``:

1. **Coarse** (``method="global"``): both sides are thinned on a voxel grid of 1/40 of
   the smaller of the two diagonals and described by FPFH features (Rusu et al. 2009, Open3D's
   implementation). Mutual nearest neighbours in feature space are correspondences; a
   RANSAC over them draws its triples from *our* seeded generator (Open3D's
   ``registration_ransac_based_on_feature_matching`` is not deterministic, even
   seeded, because its threads race), rejects triples whose edge lengths disagree, and
   counts inliers. The 24 rotations that map the scan's principal axes onto the
   reference's are candidates too, for shapes whose features are poor (smooth, symmetric).
   Each candidate is refined by ICP at two voxels; the one that then puts most scan
   points within half a voxel of the reference wins.
2. **Fine**: ICP point-to-plane at the given threshold (our own: Open3D's ICP varies
   in the last bits from run to run).

Same inputs and seed, same transform, to the last bit.

>>> import numpy as np
>>> from core.frames import rotation_about
>>> rng = np.random.default_rng(0)
>>> pts = rng.normal(size=(2000, 3)) * [0.05, 0.03, 0.01]
>>> moved = pts @ rotation_about([0, 0, 1], 2.0)[:3, :3].T + [0.3, -0.1, 0.05]
>>> reg = register(moved, pts, method="global", rng=np.random.default_rng(1))
>>> bool(np.allclose(moved @ reg.transform[:3, :3].T + reg.transform[:3, 3], pts, atol=1e-6))
True
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass, field

import numpy as np

from core.validate import check_array, check_choice, check_positive

log = logging.getLogger(__name__)

__all__ = ["Registration", "register", "ALIGN_METHODS", "LOW_FITNESS"]

#: ``scanamp evaluate --align`` choices
ALIGN_METHODS = ("none", "icp", "global")
#: below this fraction of scan points within the ICP threshold, the alignment is suspect
LOW_FITNESS = 0.5

_VOXEL_FRACTION = 1.0 / 40.0
_RANSAC_ITERATIONS = 4000
_MAX_POINTS = 60000


@dataclass(frozen=True)
class Registration:
    """``transform`` maps scan points into the reference frame (4x4, ``reference_from_scan``).

    ``fitness``: fraction of scan points within ``threshold`` of the reference after
    alignment; ``inlier_rmse``: RMS distance of those points (metres).
    """

    transform: np.ndarray
    fitness: float
    inlier_rmse: float
    threshold: float
    method: str
    details: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"method": self.method, "reference_from_scan": self.transform.tolist(),
                "fitness": self.fitness, "inlier_rmse_m": self.inlier_rmse,
                "threshold_m": self.threshold, **self.details}


def _cloud(points, normals=None):
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points)))
    if normals is not None:
        pc.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(normals))
    return pc


def _thin(points: np.ndarray, voxel: float) -> np.ndarray:
    """One point per voxel (the first, in input order): deterministic."""
    keys = np.floor((points - points.min(axis=0)) / voxel).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return points[np.sort(first)]


def _features(points: np.ndarray, voxel: float):
    import open3d as o3d

    pc = _cloud(points)
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2.5 * voxel, max_nn=30))
    pc.orient_normals_towards_camera_location(points.mean(axis=0) + 1e6)  # deterministic sign
    f = o3d.pipelines.registration.compute_fpfh_feature(
        pc, o3d.geometry.KDTreeSearchParamHybrid(radius=5.0 * voxel, max_nn=100))
    return np.asarray(f.data).T.copy()


def _kabsch(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rigid 4x4 T minimising |T a - b| (rows are points)."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = r, cb - r @ ca
    return t


def _apply(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ t[:3, :3].T + t[:3, 3]


def _ransac(src, dst, fs, fd, voxel, rng) -> list[np.ndarray]:
    from scipy.spatial import cKDTree

    if len(src) < 3 or len(dst) < 3:
        return []
    _, s2d = cKDTree(fd).query(fs)
    _, d2s = cKDTree(fs).query(fd)
    mutual = np.flatnonzero(d2s[s2d] == np.arange(len(fs)))
    if len(mutual) < 3:
        return []
    cs, cd = src[mutual], dst[s2d[mutual]]
    tri = rng.integers(0, len(mutual), size=(_RANSAC_ITERATIONS, 3))
    a, b = cs[tri], cd[tri]
    ea = np.linalg.norm(a - np.roll(a, 1, axis=1), axis=2)
    eb = np.linalg.norm(b - np.roll(b, 1, axis=1), axis=2)
    ok = np.all((np.minimum(ea, eb) >= 0.9 * np.maximum(ea, eb)) & (ea > voxel), axis=1)
    best, best_n = [], []
    for k in np.flatnonzero(ok):
        t = _kabsch(a[k], b[k])
        n = int(np.count_nonzero(np.linalg.norm(_apply(t, cs) - cd, axis=1) < 1.5 * voxel))
        best.append(t)
        best_n.append(n)
    if not best:
        return []
    order = np.argsort(best_n, kind="stable")[::-1][:5]
    refined = []
    for k in order:  # refit on the inliers of each of the five best
        inl = np.linalg.norm(_apply(best[k], cs) - cd, axis=1) < 1.5 * voxel
        refined.append(_kabsch(cs[inl], cd[inl]) if inl.sum() >= 3 else best[k])
    return refined


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


def _fitness(t, src, tree, threshold) -> float:
    d, _ = tree.query(_apply(t, src), distance_upper_bound=threshold)
    return float(np.mean(np.isfinite(d)))


def _icp(src, dst, dst_normals, init, threshold, tree=None, iterations: int = 40):
    """ICP, ours rather than Open3D's: its parallel reductions make the last bits of the
    result vary from run to run. Point-to-plane (linearised, Low 2004) with the
    reference's normals, else point-to-point (Kabsch). Returns (T, fitness, inlier RMSE)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(dst) if tree is None else tree
    t = np.array(init, dtype=np.float64)
    for _ in range(iterations):
        p = _apply(t, src)
        d, j = tree.query(p, distance_upper_bound=threshold)
        ok = np.isfinite(d)
        if ok.sum() < 6:
            break
        p, q = p[ok], dst[j[ok]]
        if dst_normals is not None:
            n = dst_normals[j[ok]]
            a = np.hstack([np.cross(p, n), n])
            b = np.einsum("ij,ij->i", q - p, n)
            x = np.linalg.lstsq(a, b, rcond=None)[0]
            step = np.eye(4)
            step[:3, :3] = _small_rotation(x[:3])
            step[:3, 3] = x[3:]
        else:
            step = _kabsch(p, q)
        t = step @ t
        if np.linalg.norm(step[:3, 3]) < 1e-9 and np.allclose(step[:3, :3], np.eye(3),
                                                               atol=1e-10):
            break
    d, _ = tree.query(_apply(t, src), distance_upper_bound=threshold)
    ok = np.isfinite(d)
    fitness = float(ok.mean())
    rmse = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")
    return t, fitness, rmse


def _small_rotation(w: np.ndarray) -> np.ndarray:
    """The rotation matrix of rotation vector ``w`` (Rodrigues), orthonormal."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-15:
        return np.eye(3)
    k = w / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


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
        s, d = _thin(src, voxel), _thin(dst, voxel)
        candidates = _ransac(s, d, _features(s, voxel), _features(d, voxel), voxel, rng)
        n_ransac = len(candidates)
        candidates += _principal_axes(s, d)
        tree = cKDTree(d)
        # every candidate is refined by ICP at two voxels, then judged at half a voxel,
        # so near-symmetric shapes are told apart by their detail
        refined = [_icp(s, d, None, t, 2.0 * voxel, tree, iterations=20)[0]
                   for t in candidates]
        scores = [_fitness(t, s, tree, 0.5 * voxel) for t in refined]
        k = int(np.argmax(scores))
        init = refined[k]
        details["coarse"] = {"source": "fpfh_ransac" if k < n_ransac else "principal_axes",
                             "fitness": scores[k], "voxel_m": voxel,
                             "candidates": len(candidates)}
    t, fitness, rmse = _icp(src, dst, reference_normals, init, threshold)
    if fitness == 0:
        log.warning("alignment found no correspondences within %.4g m; scoring unaligned",
                    threshold)
        return Registration(np.eye(4), 0.0, float("nan"), threshold, method, details)
    if fitness < LOW_FITNESS:
        log.debug("alignment is doubtful: only %.0f%% of the scan lies within %.3g m of the "
                    "reference after %s alignment; the scores below may mean nothing",
                    100 * fitness, threshold, method)
    return Registration(t, fitness, rmse, threshold, method, details)
