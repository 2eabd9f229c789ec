"""Coarse rigid alignment from local shape features: FPFH descriptors, matches in feature
space, and a seeded RANSAC over the matches.

FPFH (Rusu, Blodow and Beetz 2009, doi:10.1109/ROBOT.2009.5152473) comes from Open3D.
The RANSAC is ours: Open3D's ``registration_ransac_based_on_feature_matching`` is not
deterministic even when seeded (its threads race for the best hypothesis). Here every
triple is drawn from the caller's generator up front, hypotheses are scored in a fixed
order, and ties are broken by index: same generator state, same answer.

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> src = rng.normal(size=(300, 3))
>>> T = np.eye(4); T[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0] * -1; T[:3, 3] = 1.0
>>> T[:3, :3] *= np.linalg.det(T[:3, :3])
>>> dst = src @ T[:3, :3].T + T[:3, 3]
>>> pairs = np.stack([np.arange(300), np.arange(300)], axis=1)
>>> pairs[:100, 1] = rng.permutation(300)[:100]  # a third of the matches are wrong
>>> best = ransac_rigid(src, dst, pairs, inlier=0.05, rng=np.random.default_rng(1))
>>> bool(np.allclose(best[0], T, atol=1e-9))
True
"""

from __future__ import annotations

import numpy as np

from core.frames import transform_points

__all__ = ["fpfh", "match_features", "ransac_rigid", "kabsch"]


def fpfh(points: np.ndarray, normals: np.ndarray, radius: float) -> np.ndarray:
    """FPFH descriptors ``(n, 33) float64`` of oriented points over a ball of ``radius``."""
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points)))
    pc.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(normals))
    f = o3d.pipelines.registration.compute_fpfh_feature(
        pc, o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=100))
    return np.asarray(f.data).T.copy()


def match_features(f_src: np.ndarray, f_dst: np.ndarray, *, min_mutual: int = 30) -> np.ndarray:
    """Matches ``(k, 2) int64`` (source index, target index): mutual nearest neighbours in
    feature space, or every source's nearest target when fewer than ``min_mutual`` are
    mutual."""
    if len(f_src) == 0 or len(f_dst) == 0:
        return np.zeros((0, 2), np.int64)
    s2d, d2s = _nearest_both(f_src, f_dst)
    src = np.arange(len(f_src))
    mutual = d2s[s2d] == src
    if mutual.sum() >= min_mutual:
        src = src[mutual]
    return np.stack([src, s2d[src]], axis=1).astype(np.int64)


def _nearest_both(a: np.ndarray, b: np.ndarray, chunk: int = 2048):
    """Each row's nearest row of the other set (squared Euclidean in float32, ties to the
    lower index). Both ways are searched along contiguous rows (one product per way):
    cheaper than reducing one product along its columns."""
    a = np.ascontiguousarray(a, np.float32)
    b = np.ascontiguousarray(b, np.float32)
    return _nearest(a, b, chunk), _nearest(b, a, chunk)


def _nearest(a: np.ndarray, b: np.ndarray, chunk: int) -> np.ndarray:
    """Index of the nearest row of ``b`` for each row of ``a`` (float32)."""
    bb = np.einsum("ij,ij->i", b, b)
    out = np.empty(len(a), np.int64)
    for s in range(0, len(a), chunk):
        d = a[s:s + chunk] @ b.T   # |a|^2 is constant per row
        d *= -2.0
        d += bb
        out[s:s + chunk] = np.argmin(d, axis=1)
    return out


def kabsch(a: np.ndarray, b: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """Rigid 4x4 ``T`` minimising ``sum w |T a - b|^2``; batched over a leading axis too:
    ``a, b : (..., n, 3)``."""
    w = np.ones(a.shape[:-1]) if w is None else w
    ws = w.sum(axis=-1, keepdims=True)[..., None]
    ca = (w[..., None] * a).sum(axis=-2, keepdims=True) / ws
    cb = (w[..., None] * b).sum(axis=-2, keepdims=True) / ws
    h = np.swapaxes(w[..., None] * (a - ca), -1, -2) @ (b - cb)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.swapaxes(vt, -1, -2) @ np.swapaxes(u, -1, -2)))
    fix = np.ones(u.shape[:-2] + (3,))
    fix[..., 2] = np.where(d == 0, 1.0, d)
    r = np.swapaxes(vt, -1, -2) @ (fix[..., :, None] * np.swapaxes(u, -1, -2))
    T = np.zeros(u.shape[:-2] + (4, 4))
    T[..., :3, :3] = r
    T[..., :3, 3] = cb[..., 0, :] - (r @ ca[..., 0, :, None])[..., 0]
    T[..., 3, 3] = 1.0
    return T


def ransac_rigid(src: np.ndarray, dst: np.ndarray, matches: np.ndarray, *, inlier: float,
                 rng: np.random.Generator, iterations: int = 6000, keep: int = 6,
                 min_edge: float | None = None, chunk: int = 500) -> list[np.ndarray]:
    """The ``keep`` best rigid ``dst_from_src`` hypotheses from triples of ``matches``.

    Parameters
    ----------
    src : (n, 3) float64
    dst : (m, 3) float64
    matches : (k, 2) int64
        Candidate correspondences (source index, target index).
    inlier : float
        A match is an inlier when the hypothesis brings it within this distance (metres).
    rng : numpy.random.Generator
        Draws the triples.
    iterations : int
        Triples drawn; those whose edge lengths disagree by more than 10 % are skipped.
    min_edge : float, optional
        Triples with an edge this short or shorter are skipped too (metres; default
        ``2 * inlier``: a short triple's rotation is poorly determined).

    Returns
    -------
    list of (4, 4) float64
        Best first (most inliers, refitted on them); distinct hypotheses only; empty
        when no triple survives.
    """
    if len(matches) < 3:
        return []
    cs, cd = src[matches[:, 0]], dst[matches[:, 1]]
    tri = rng.integers(0, len(matches), size=(iterations, 3))
    a, b = cs[tri], cd[tri]
    ea = np.linalg.norm(a - np.roll(a, 1, axis=1), axis=2)
    eb = np.linalg.norm(b - np.roll(b, 1, axis=1), axis=2)
    min_edge = 2 * inlier if min_edge is None else min_edge
    ok = np.all((np.minimum(ea, eb) >= 0.9 * np.maximum(ea, eb)) & (ea > min_edge), axis=1)
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return []
    hyp = kabsch(a[idx], b[idx])
    # preemptive scoring: every hypothesis on a fixed subset of the matches, the best
    # five hundred on all of them
    sub = np.arange(len(cs)) if len(cs) <= 400 else np.sort(
        rng.choice(len(cs), 400, replace=False))
    counts = _count_inliers(hyp, cs[sub], cd[sub], inlier, chunk)
    top = np.argsort(-counts, kind="stable")[:500]
    hyp = hyp[top]
    counts = _count_inliers(hyp, cs, cd, inlier, chunk)
    order = np.argsort(-counts, kind="stable")
    out: list[np.ndarray] = []
    for k in order:
        if len(out) >= keep or counts[k] < 3:
            break
        inl = np.sum((transform_points(hyp[k], cs) - cd) ** 2, axis=1) < inlier ** 2
        T = kabsch(cs[inl], cd[inl])
        if all(_differ(T, o, inlier) for o in out):
            out.append(T)
    return out


def _count_inliers(hyp, cs, cd, inlier, chunk):
    counts = np.empty(len(hyp), np.int64)
    for s in range(0, len(hyp), chunk):
        h = hyp[s:s + chunk]
        moved = np.einsum("hij,nj->hni", h[:, :3, :3], cs) + h[:, None, :3, 3]
        counts[s:s + chunk] = np.count_nonzero(
            np.sum((moved - cd) ** 2, axis=2) < inlier ** 2, axis=1)
    return counts


def _differ(a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    d = a @ np.linalg.inv(b)
    return bool(np.linalg.norm(d[:3, 3]) > 2 * tol or np.trace(d[:3, :3]) < 3 - 1e-3)
