"""Scores of a LiDAR result against the truth: tree detection, tree heights, the terrain.

Trees are matched one to one by lidaRtRee's rule (``tree_matching``; Monnet 2011, Ph.D.
thesis, Grenoble, pp. 53-55): a reference tree and a detected tree may pair when their 3-D
distance (x, y and height) is below ``delta_ground + h_prec * reference height`` (2.1 m +
0.14 h); the pairs are taken in increasing order of distance / that limit, each tree at most
once. Detection rate = matched / reference trees; omission = 1 - detection; commission =
unmatched detections / detections; F = 2 matched / (reference + detected).

>>> import numpy as np
>>> ref = np.array([[0.0, 0.0, 20.0], [10.0, 0.0, 20.0]])
>>> det = np.array([[0.5, 0.0, 19.0], [30.0, 0.0, 20.0]])
>>> s = tree_scores(ref, det)
>>> s["matched"], s["detection"], s["commission"], s["f"]
(1, 0.5, 0.5, 0.5)
"""

from __future__ import annotations

import numpy as np

from core.io.raster import Raster
from core.validate import check_array

__all__ = ["match_trees", "tree_scores", "dtm_errors", "evaluate_lidar", "lidar_table",
           "DELTA_GROUND", "H_PREC"]

DELTA_GROUND = 2.1  # metres: lidaRtRee's buffer around the stem
H_PREC = 0.14  # of the reference tree's height: its buffer around the apex


def match_trees(reference: np.ndarray, detected: np.ndarray, *,
                delta_ground: float = DELTA_GROUND, h_prec: float = H_PREC) -> np.ndarray:
    """One-to-one pairs of reference and detected trees.

    Parameters
    ----------
    reference, detected : (n, 3), (m, 3) float64
        ``x, y, height`` of each tree, metres.

    Returns
    -------
    (k, 2) int64
        Row of the reference tree and row of the detected tree of each pair, in the
        order they were taken (most certain first).
    """
    r = check_array(reference, "reference", shape=(None, 3))
    d = check_array(detected, "detected", shape=(None, 3))
    if len(r) == 0 or len(d) == 0:
        return np.empty((0, 2), np.int64)
    from scipy.spatial import cKDTree

    limit = delta_ground + h_prec * r[:, 2]
    # candidate pairs only within the largest limit (a k-d tree, not the full matrix)
    pairs = cKDTree(r).query_ball_tree(cKDTree(d), float(limit.max()))
    ri = np.repeat(np.arange(len(r)), [len(p) for p in pairs])
    di = np.fromiter((j for p in pairs for j in p), np.int64, count=len(ri))
    if len(ri) == 0:
        return np.empty((0, 2), np.int64)
    index = np.linalg.norm(r[ri] - d[di], axis=1) / limit[ri]
    ok = index < 1.0
    ri, di, index = ri[ok], di[ok], index[ok]
    order = np.lexsort((di, ri, index))
    used_r = np.zeros(len(r), bool)
    used_d = np.zeros(len(d), bool)
    out = []
    for k in order:
        a, b = ri[k], di[k]
        if not used_r[a] and not used_d[b]:
            used_r[a] = used_d[b] = True
            out.append((a, b))
    return np.array(out, np.int64).reshape(-1, 2)


def tree_scores(reference: np.ndarray, detected: np.ndarray, **kw) -> dict:
    """Detection, omission, commission, F and the heights' errors of matched trees.

    Parameters
    ----------
    reference, detected : (n, 3), (m, 3) float64
        ``x, y, height``.
    **kw
        ``delta_ground``, ``h_prec`` of :func:`match_trees`.

    Returns
    -------
    dict
        ``reference``, ``detected``, ``matched`` (counts), ``detection``, ``omission``,
        ``commission``, ``f`` (fractions; NaN when undefined), ``height_rmse``,
        ``height_bias`` (detected - reference, metres), ``position_rmse`` (horizontal, m).
    """
    r = check_array(reference, "reference", shape=(None, 3))
    d = check_array(detected, "detected", shape=(None, 3))
    pairs = match_trees(r, d, **kw)
    n, m, k = len(r), len(d), len(pairs)
    nan = float("nan")
    dh = d[pairs[:, 1], 2] - r[pairs[:, 0], 2] if k else np.empty(0)
    dxy = (np.linalg.norm(d[pairs[:, 1], :2] - r[pairs[:, 0], :2], axis=1) if k
           else np.empty(0))
    return {
        "reference": n, "detected": m, "matched": k,
        "detection": k / n if n else nan,
        "omission": 1 - k / n if n else nan,
        "commission": (m - k) / m if m else nan,
        "f": 2 * k / (n + m) if n + m else nan,
        "height_rmse": float(np.sqrt(np.mean(dh ** 2))) if k else nan,
        "height_bias": float(np.mean(dh)) if k else nan,
        "position_rmse": float(np.sqrt(np.mean(dxy ** 2))) if k else nan,
    }


def dtm_errors(dtm: Raster, reference: Raster | None = None, *,
               points: np.ndarray | None = None) -> dict:
    """Errors of a DTM against a reference DTM (at its cells) or reference ground points.

    Parameters
    ----------
    dtm : Raster
    reference : Raster, optional
        Sampled (bilinear) at the cell centres of ``dtm`` that it covers.
    points : (n, 3) float64, optional
        Reference ground points; ``dtm`` is sampled at them.

    Returns
    -------
    dict
        ``rmse``, ``bias`` (dtm - reference), ``p95_abs`` (metres) and ``n`` (samples).
    """
    if (reference is None) == (points is None):
        raise ValueError("reference, points: expected exactly one of them")
    if reference is not None:
        xs, ys = dtm.centres()
        X, Y = np.meshgrid(xs, ys)
        want = reference.sample(X.ravel(), Y.ravel())
        have = dtm.values.ravel()
    else:
        p = check_array(points, "points", shape=(None, 3))
        want = p[:, 2]
        have = dtm.sample(p[:, 0], p[:, 1])
    e = have - want
    e = e[np.isfinite(e)]
    if len(e) == 0:
        raise ValueError("reference: no overlap with the DTM")
    return {"rmse": float(np.sqrt(np.mean(e ** 2))), "bias": float(np.mean(e)),
            "p95_abs": float(np.percentile(np.abs(e), 95)), "n": int(len(e))}


def evaluate_lidar(result_dir, truth_dir) -> dict:
    """Score a ``reconstruct lidar`` folder against a forest scene's truth.

    Parameters
    ----------
    result_dir : path
        Holds ``trees.csv`` and ``dtm.tif`` (``scanamp reconstruct lidar``).
    truth_dir : path
        Holds ``trees.csv`` (``x, y, height``) and ``dtm.tif`` (``scanamp scene forest``).

    Returns
    -------
    dict
        ``trees`` (:func:`tree_scores`, over the reference trees inside the result's DTM)
        and ``dtm`` (:func:`dtm_errors` at the result's cells the truth covers).
    """
    from pathlib import Path

    from core.io.raster import read_raster
    from core.io.trees import read_tree_table

    result_dir, truth_dir = Path(result_dir), Path(truth_dir)
    det = read_tree_table(result_dir / "trees.csv", allow_empty=True)
    ref = read_tree_table(truth_dir / "trees.csv")
    dtm = read_raster(result_dir / "dtm.tif")
    truth_dtm = read_raster(truth_dir / "dtm.tif")
    xs, ys = dtm.centres()
    inside = ((ref["x"] >= xs[0]) & (ref["x"] <= xs[-1]) & (ref["y"] >= ys[0])
              & (ref["y"] <= ys[-1]))
    r = np.column_stack([ref["x"], ref["y"], ref["height"]])[inside]
    d = np.column_stack([det["x"], det["y"], det["height"]])
    return {"trees": tree_scores(r, d), "dtm": dtm_errors(dtm, truth_dtm),
            "reference_trees_outside": int((~inside).sum())}


def lidar_table(scores: dict) -> str:
    """The figures of :func:`evaluate_lidar` as a few aligned lines."""
    t, g = scores["trees"], scores["dtm"]
    return "\n".join([
        f"trees      reference {t['reference']}  detected {t['detected']}  matched "
        f"{t['matched']}",
        f"detection  {t['detection']:.3f}  omission {t['omission']:.3f}  commission "
        f"{t['commission']:.3f}  F {t['f']:.3f}",
        f"height     RMSE {t['height_rmse']:.2f} m  bias {t['height_bias']:+.2f} m  "
        f"(position RMSE {t['position_rmse']:.2f} m)",
        f"DTM        RMSE {g['rmse']:.3f} m  bias {g['bias']:+.3f} m  P95 |e| {g['p95_abs']:.3f} m"
        f"  ({g['n']} cells)",
    ])
