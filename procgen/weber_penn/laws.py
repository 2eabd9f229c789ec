"""Measuring a tree as foresters and botanists measure real ones, on its QSM.

- :func:`leonardo_exponents`: at every fork the exponent ``D`` with
  ``d**D = sum d_i**D`` (Leonardo's rule; Eloy 2011 measured ``D`` in 1.8-2.3 on real
  trees). A fork is a cylinder with two or more children (its extension and the branches
  leaving at its end).
- :func:`taper`: along each branch, the share of steps where the radius does not grow, and
  the radius lost a metre.
- :func:`branching_angles`: the angle between a branch's first cylinder and its parent's,
  per branch order; :func:`divergence_angles`: the turn about the parent's axis between
  successive branches (137.5 deg, the golden angle, in spiral phyllotaxis).
- :func:`dbh` and :func:`allometric_exponent`: the stem's diameter at breast height and the
  exponent ``b`` of ``height ~ dbh**b`` across trees (0.45-0.8 in forest data).
- :func:`crown_profile` and :func:`envelope_correlation`: the horizontal reach of the limbs
  leaving each height of the crown against the species' shape function.

All take a :class:`core.io.qsm.QSM`, so they measure real TreeQSM models as well.
"""

from __future__ import annotations

import numpy as np

from core.io.qsm import QSM

__all__ = ["leonardo_exponents", "taper", "branching_angles", "divergence_angles", "dbh",
           "allometric_exponent", "crown_profile", "crown_silhouette", "envelope_correlation",
           "species_envelope", "BREAST_HEIGHT"]

BREAST_HEIGHT = 1.3  # metres above the stem's base


def _children(qsm: QSM):
    pidx = qsm.parent_index()
    order = np.argsort(pidx, kind="stable")
    sp = pidx[order]
    lo = np.searchsorted(sp, np.arange(len(qsm)), side="left")
    hi = np.searchsorted(sp, np.arange(len(qsm)), side="right")
    return pidx, order, lo, hi


def leonardo_exponents(qsm: QSM, *, min_radius: float = 0.0) -> np.ndarray:
    """The exponent ``D`` solving ``sum (d_i / d)**D = 1`` at each fork whose parent radius
    is at least ``min_radius`` (forks where it has no root in [0.5, 12] are left out)."""
    _, order, lo, hi = _children(qsm)
    forks = np.flatnonzero((hi - lo >= 2) & (qsm.radius >= max(min_radius, 1e-12)))
    if not len(forks):
        return np.zeros(0)
    k = (hi - lo)[forks]
    rep = np.repeat(np.arange(len(forks)), k)
    kid = order[np.concatenate([np.arange(a, b)
                                for a, b in zip(lo[forks], hi[forks], strict=True)])]
    ratio = qsm.radius[kid] / qsm.radius[forks][rep]

    def f(D):
        s = np.zeros(len(forks))
        np.add.at(s, rep, np.where(ratio > 0, ratio, 0.0) ** D[rep])
        return s - 1.0
    a, b = np.full(len(forks), 0.5), np.full(len(forks), 12.0)
    fa, fb = f(a), f(b)
    ok = (fa > 0) & (fb < 0)
    for _ in range(50):  # f falls with D when every child is thinner than the parent
        m = 0.5 * (a + b)
        fm = f(m)
        a = np.where(fm > 0, m, a)
        b = np.where(fm > 0, b, m)
    return (0.5 * (a + b))[ok]


def taper(qsm: QSM) -> dict:
    """Along each branch: ``monotone`` the share of consecutive cylinders whose radius does
    not grow, ``per_metre`` the median radius lost a metre along the branches (m/m)."""
    ext = qsm.extension
    idx = np.searchsorted(qsm.id, ext)  # ids are sorted in scanamp's and TreeQSM's tables
    has = (ext > 0) & (idx < len(qsm))
    i = np.flatnonzero(has)
    j = idx[i]
    j_ok = qsm.id[j] == ext[i]
    i, j = i[j_ok], j[j_ok]
    r0, r1 = qsm.radius[i], qsm.radius[j]
    mono = float(np.mean(r1 <= r0 * (1 + 1e-9))) if len(i) else float("nan")
    rate = (r0 - r1) / np.maximum(qsm.length[i], 1e-9)
    return {"monotone": mono, "per_metre": float(np.median(rate)) if len(i) else float("nan")}


def _first_cylinders(qsm: QSM):
    """Rows of each branch's first cylinder (not the root) and of its parent cylinder."""
    pidx = qsm.parent_index()
    first = np.flatnonzero((pidx >= 0) & (qsm.branch != qsm.branch[np.maximum(pidx, 0)]))
    return first, pidx[first]


def branching_angles(qsm: QSM) -> dict[int, np.ndarray]:
    """Angles (degrees) between each branch's first cylinder and its parent cylinder, by the
    branch's order."""
    first, par = _first_cylinders(qsm)
    cos = np.clip((qsm.axis[first] * qsm.axis[par]).sum(1), -1, 1)
    ang = np.degrees(np.arccos(cos))
    orders = qsm.branch_order[first]
    return {int(o): ang[orders == o] for o in np.unique(orders)}


def divergence_angles(qsm: QSM, *, parent_order: int = 0) -> np.ndarray:
    """Turns (degrees, 0-180) about the parent's axis between successive branches leaving
    the branches of ``parent_order`` at distinct heights (whorl mates excluded)."""
    first, par = _first_cylinders(qsm)
    sel = qsm.branch_order[par] == parent_order
    first, par = first[sel], par[sel]
    a = qsm.axis[par]
    d = qsm.axis[first] - (qsm.axis[first] * a).sum(1, keepdims=True) * a
    # a fixed frame about each parent axis
    ref = np.where(np.abs(a[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(a, ref)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(a, e1)
    phi = np.degrees(np.arctan2((d * e2).sum(1), (d * e1).sum(1)))
    pos = qsm.start[first]
    br = qsm.branch[par]
    along = (pos * a).sum(1)
    order = np.lexsort((along, br))
    br, along, phi = br[order], along[order], phi[order]
    same = (br[1:] == br[:-1]) & (along[1:] - along[:-1] > 1e-6)
    turn = np.abs((phi[1:] - phi[:-1] + 180.0) % 360.0 - 180.0)
    return turn[same]


def dbh(qsm: QSM) -> float:
    """The stem's diameter (m) at 1.3 m above its base: the order-0 cylinder there."""
    stem = np.flatnonzero(qsm.branch == qsm.branch[np.flatnonzero(qsm.parent == 0)[0]])
    z0 = qsm.start[stem, 2].min()
    zs, ze = qsm.start[stem, 2] - z0, qsm.end[stem, 2] - z0
    hit = stem[(zs <= BREAST_HEIGHT) & (ze > BREAST_HEIGHT)]
    if not len(hit):
        hit = stem[[np.argmin(np.abs(zs - BREAST_HEIGHT))]]
    return float(2 * qsm.radius[hit[0]])


def allometric_exponent(heights, diameters) -> float:
    """The exponent ``b`` of ``height = a dbh**b`` fitted in log-log by least squares."""
    h, d = np.log(np.asarray(heights, float)), np.log(np.asarray(diameters, float))
    return float(np.polyfit(d, h, 1)[0])


def crown_silhouette(qsm: QSM, *, base: float, bins: int = 10, extra_points=None):
    """The crown's radius along its height: in each of ``bins`` slices from ``base`` (m
    above the stem's base) to the top, the 95th percentile of the horizontal distance from
    the stem's base of the cylinders' ends (and of ``extra_points`` (k, 3), e.g. leaves)
    in that slice.

    Returns ``(ratio, radius)``: each slice's ``(top - z) / (top - base)`` at its middle,
    as in Weber & Penn's shape ratio, and the crown radius there (m); NaN for empty slices.
    """
    stem = qsm.branch_order == 0
    root = np.flatnonzero(qsm.parent == 0)[0]
    origin = qsm.start[root]
    pts = qsm.end[qsm.branch_order >= 1]
    if extra_points is not None and len(extra_points):
        pts = np.concatenate([pts, np.asarray(extra_points, float)])
    z = pts[:, 2] - origin[2]
    top = max(qsm.end[stem, 2].max() - origin[2], z.max() if len(z) else 0.0)
    r = np.hypot(pts[:, 0] - origin[0], pts[:, 1] - origin[1])
    edges = np.linspace(base, top, bins + 1)
    k = np.searchsorted(edges, z, side="right") - 1
    prof = np.full(bins, np.nan)
    for b in range(bins):
        m = k == b
        if m.sum() >= 3:
            prof[b] = np.percentile(r[m], 95)
    mid = 0.5 * (edges[:-1] + edges[1:])
    return (top - mid) / max(top - base, 1e-9), prof


def crown_profile(qsm: QSM, *, base_size: float, bins: int = 10):
    """The crown's radius along the stem, as Weber & Penn's shape function sets it: for each
    of ``bins`` slices of the stem from ``base_size`` (a fraction of the stem's height, the
    species' ``BaseSize``) to its top, the largest
    reach (3-D distance from the limb's base to its farthest cylinder end) of the limbs
    (order-1 branches and all that grows on them) leaving that slice.

    Returns ``(ratio, reach)``: each slice's ``(top - z) / (top - base)`` at its middle and
    the reach (m); NaN for slices without limbs.
    """
    pidx = qsm.parent_index()
    limb = np.full(len(qsm), -1)
    first, _ = _first_cylinders(qsm)
    lim = first[qsm.branch_order[first] == 1]
    limb[lim] = lim
    while True:  # every cylinder of order >= 1 takes its parent's limb
        up = np.where(pidx >= 0, limb[np.maximum(pidx, 0)], -1)
        new = np.where((limb < 0) & (qsm.branch_order >= 1), up, limb)
        if np.array_equal(new, limb):
            break
        limb = new
    stem = qsm.branch_order == 0
    z0 = qsm.start[stem, 2].min()
    top = qsm.end[stem, 2].max() - z0
    base = base_size * top
    sel = np.flatnonzero(limb >= 0)
    reach = np.linalg.norm(qsm.end[sel] - qsm.start[limb[sel]], axis=1)
    best = np.zeros(len(qsm))
    np.maximum.at(best, limb[sel], reach)
    z_limb = qsm.start[lim, 2] - z0
    edges = np.linspace(base, top, bins + 1)
    k = np.clip(np.searchsorted(edges, z_limb, side="right") - 1, 0, bins - 1)
    inside = (z_limb >= base) & (z_limb <= top)
    prof = np.full(bins, np.nan)
    for b in range(bins):
        m = inside & (k == b)
        if m.any():
            prof[b] = best[lim[m]].max()
    mid = 0.5 * (edges[:-1] + edges[1:])
    return (top - mid) / max(top - base, 1e-9), prof


def envelope_correlation(ratio, reach, shape_values) -> float:
    """Pearson correlation between a crown profile and the shape function's values at its
    slices (NaN slices left out); NaN when the shape is constant."""
    ok = np.isfinite(reach)
    a, b = np.asarray(reach)[ok], np.asarray(shape_values)[ok]
    if len(a) < 3 or np.std(b) < 1e-9 or np.std(a) < 1e-12:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def species_envelope(qsm: QSM, tree_params, *, leaves=None) -> tuple[float, str]:
    """The correlation between a tree's crown and its species' shape function, and which
    profile was compared: the limbs' reach against ``Shape`` (:func:`crown_profile`), or for
    a pruned species (``PruneRatio`` > 0) the crown's silhouette (:func:`crown_silhouette`,
    with ``leaves`` (k, 3) if given) against the pruning envelope, which bounds the
    silhouette. NaN for a constant shape (cylindrical), where no correlation is defined."""
    from procgen.weber_penn.shapes import shape_ratio

    p = tree_params
    if p["PruneRatio"] > 0:
        stem = qsm.branch_order == 0
        top = qsm.end[stem, 2].max() - qsm.start[stem, 2].min()
        ratio, prof = crown_silhouette(qsm, base=p["BaseSize"] * top, extra_points=leaves)
        return (envelope_correlation(ratio, prof, shape_ratio(8, ratio, prune=p.tree)),
                "silhouette / envelope")
    ratio, reach = crown_profile(qsm, base_size=p["BaseSize"])
    return envelope_correlation(ratio, reach, shape_ratio(p["Shape"], ratio)), "limbs / shape"
