"""A truth-free check of a sparse model: do its cameras explain the matches it was built on?

The mapper reports how many views it registered, not whether it put them in the right
places. A scene that repeats itself fools it without a trace in that count: a temple with
a 180-degree symmetry seen from a ring of 16 views looks the same from opposite sides, the
matches between opposite views are as good as those between neighbours, and the mapper
may fold the ring onto half of itself (views ``i`` and ``i + 8`` at one pose) and still
report 16 of 16. What betrays it is the verified matches between registered views that
the model's own epipolar geometry rejects: on a right model (its cameras, its intrinsics)
nearly every inlier of every verified pair lies within the verification's threshold of
its epipolar line; a folded or otherwise wrong model leaves whole pairs unexplained.

:func:`check_model` measures, for every verified pair of registered views, the share of
its inlier matches whose Sampson distance to the model's epipolar geometry is within
``explained_px`` (4 px: COLMAP's two-view verification threshold, so a match the
verification kept and the model rejects is a contradiction, not noise). A pair with less
than half of its inliers explained is *contradicted*; the model fails when more than
``max_contradicted`` of the pairs are (a repeated structure gives a few such pairs on a
right model too: the share, not their presence, is the cue). It also names views that
the model put at one pose (centres closer than ``coincide`` of the median distance
between cameras, orientations within one degree): the same photo twice, or a symmetric
scene folded onto itself. That alone does not fail the model (a burst of photos from one
spot is legitimate), but it names the cause when the pairs are contradicted.

References
----------
J. Heinly, E. Dunn, J.-M. Frahm, "Correcting for duplicate scene structure in
sparse 3D reconstruction", ECCV 2014 (the folding of symmetric scenes).
R. Hartley, A. Zisserman, "Multiple View Geometry", 2nd ed., 2004, sec. 11.4.3
(Sampson distance).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.frames import rotation_angle_deg
from core.validate import check_array

__all__ = ["SelfCheck", "sampson_distance", "check_model", "check_reconstruction"]

log = logging.getLogger(__name__)


@dataclass
class SelfCheck:
    """What :func:`check_model` found.

    Attributes
    ----------
    pairs : int
        Verified pairs between registered views (with at least one inlier match).
    explained_share : float or None
        Of all their inlier matches, the share the model explains (None without pairs).
    contradicted : list of (str, str, int, float)
        The pairs with less than half their inliers explained: names, inliers, share.
    coincident : list of (str, str)
        Views the model put at one pose.
    ok : bool
        At most ``max_contradicted`` of the pairs contradicted.
    warnings : list of str
        One sentence per finding, naming the views.
    """

    pairs: int
    explained_share: float | None
    contradicted: list = field(default_factory=list)
    coincident: list = field(default_factory=list)
    ok: bool = True
    warnings: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"ok": self.ok, "pairs": self.pairs,
                "explained_share": self.explained_share,
                "contradicted_pairs": [{"views": [a, b], "inliers": n, "explained": s}
                                       for a, b, n, s in self.contradicted],
                "coincident_views": [list(p) for p in self.coincident],
                "warnings": list(self.warnings)}


def sampson_distance(F: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """First-order geometric distance (pixels) of matches ``x1 <-> x2`` ((m, 2) each) to
    the epipolar geometry ``x2^T F x1 = 0`` ((3, 3)); (m,) float64.

    >>> F = np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0]], float)  # a horizontal shift
    >>> sampson_distance(F, np.array([[5.0, 2.0]]), np.array([[9.0, 5.0]])).round(6)
    array([2.12132])
    """
    F = check_array(F, "F", shape=(3, 3))
    x1 = check_array(x1, "x1", shape=(None, 2))
    x2 = check_array(x2, "x2", shape=(len(x1), 2))
    h1, h2 = np.c_[x1, np.ones(len(x1))], np.c_[x2, np.ones(len(x2))]
    fx1, ftx2 = h1 @ F.T, h2 @ F
    den = fx1[:, 0] ** 2 + fx1[:, 1] ** 2 + ftx2[:, 0] ** 2 + ftx2[:, 1] ** 2
    return np.abs(np.sum(h2 * fx1, axis=1)) / np.sqrt(np.maximum(den, 1e-300))


def _fundamental(T1: np.ndarray, T2: np.ndarray, K1: np.ndarray, K2: np.ndarray) -> np.ndarray:
    """F of two cameras (cam_from_world (4, 4), K (3, 3)): ``x2^T F x1 = 0``."""
    T = T2 @ np.linalg.inv(T1)  # cam2_from_cam1
    R, t = T[:3, :3], T[:3, 3]
    tx = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    return np.linalg.inv(K2).T @ (tx @ R) @ np.linalg.inv(K1)


def check_model(cam_from_world: Mapping[str, np.ndarray], K: Mapping[str, np.ndarray],
                matches: Mapping[tuple[str, str], tuple[np.ndarray, np.ndarray]], *,
                explained_px: float = 4.0, max_contradicted: float = 0.1,
                coincide: float = 0.01) -> SelfCheck:
    """Check a model's cameras against verified matches (module docstring).

    Parameters
    ----------
    cam_from_world : mapping name -> (4, 4) float64
        The registered views.
    K : mapping name -> (3, 3) float64
        Their intrinsics (pinhole; keypoints undistorted or distortion negligible).
    matches : mapping (name, name) -> ((m, 2), (m, 2)) float64
        Each verified pair's inlier keypoints (pixels); pairs with an unregistered view
        are skipped.
    explained_px : float
        A match within this Sampson distance of the model's epipolar line is explained.
    max_contradicted : float
        The largest share of contradicted pairs a model passes with.
    coincide : float
        Views closer than this share of the median distance between the cameras (and
        within one degree) are at one pose.
    """
    if explained_px <= 0:
        raise ValueError(f"explained_px: expected > 0, got {explained_px}")
    if not 0 <= max_contradicted <= 1:
        raise ValueError(f"max_contradicted: expected a share in [0, 1], got "
                         f"{max_contradicted}")
    total = explained = 0
    pairs, contradicted = 0, []
    for (a, b), (x1, x2) in matches.items():
        if a not in cam_from_world or b not in cam_from_world or len(x1) == 0:
            continue
        F = _fundamental(cam_from_world[a], cam_from_world[b], K[a], K[b])
        ok = sampson_distance(F, np.asarray(x1, float), np.asarray(x2, float)) <= explained_px
        pairs += 1
        total += len(ok)
        explained += int(ok.sum())
        share = float(ok.mean())
        if share < 0.5:
            contradicted.append((a, b, len(ok), share))
    contradicted.sort(key=lambda c: (c[3], -c[2]))
    coincident = _coincident(cam_from_world, coincide)
    check = SelfCheck(pairs, explained / total if total else None, contradicted, coincident)
    check.ok = pairs == 0 or len(contradicted) <= max_contradicted * pairs
    if not check.ok:
        worst = ", ".join(f"{a} / {b} ({n} inliers, {100 * s:.0f} % explained)"
                          for a, b, n, s in contradicted[:3])
        check.warnings.append(
            f"the model contradicts {len(contradicted)} of its {pairs} verified pairs "
            f"(it explains {100 * check.explained_share:.0f} % of their matches), e.g. "
            f"{worst}: the views are not where the matches put them")
        if coincident:
            check.warnings.append(
                f"{len(coincident)} pairs of views were put at one pose ("
                + ", ".join(f"{a} = {b}" for a, b in coincident[:4])
                + "): a scene that looks the same from those places (symmetric or "
                  "repeated structure) folded onto itself")
    return check


def _coincident(cam_from_world: Mapping[str, np.ndarray], coincide: float) -> list:
    names = sorted(cam_from_world)
    if len(names) < 3:
        return []
    T = [np.asarray(cam_from_world[n], float) for n in names]
    C = np.array([-t[:3, :3].T @ t[:3, 3] for t in T])
    d = np.linalg.norm(C[:, None] - C[None], axis=2)
    scale = float(np.median(d[np.triu_indices(len(names), 1)]))
    out = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if d[i, j] <= coincide * scale and \
                    rotation_angle_deg(T[i][:3, :3] @ T[j][:3, :3].T) <= 1.0:
                out.append((names[i], names[j]))
    return out


def check_reconstruction(rec, database: str | Path, **options) -> SelfCheck:
    """:func:`check_model` of a pycolmap reconstruction against the verified matches of
    a COLMAP database (the one it was mapped from)."""
    import pycolmap

    from reconstruct.camera_files import image_cam_from_world

    posed = {im.name: im for im in rec.images.values() if im.has_pose}
    db = pycolmap.Database.open(str(database))
    try:
        names = {im.image_id: im.name for im in db.read_all_images()}
        ids, geoms = db.read_two_view_geometries() if db.num_verified_image_pairs() \
            else ([], [])
        keypoints = {}
        matches = {}
        for pid, g in zip(ids, geoms, strict=False):
            a, b = pycolmap.pair_id_to_image_pair(pid)
            m = np.asarray(g.inlier_matches)
            if names[a] not in posed or names[b] not in posed or len(m) == 0:
                continue
            for i in (a, b):
                if i not in keypoints:
                    keypoints[i] = db.read_keypoints(i)[:, :2].astype(np.float64)
            matches[(names[a], names[b])] = (keypoints[a][m[:, 0]], keypoints[b][m[:, 1]])
    finally:
        db.close()
    poses = {n: image_cam_from_world(im) for n, im in posed.items()}
    K = {n: np.asarray(im.camera.calibration_matrix(), float) for n, im in posed.items()}
    return check_model(poses, K, matches, **options)
