"""Individual trees from a canopy height model: tops by local maxima, crowns by watershed.

Tops: the CHM is smoothed (Gaussian, ``smooth`` metres: about one spacing of the survey's
first returns), and a cell is a tree top when it is at least ``min_height`` tall and no
higher top lies within a disc whose diameter grows with its height, ``window_base +
window_slope * height`` (the base about two point spacings) (the variable window of Popescu
and Wynne 2004, doi:10.14358/PERS.70.5.589). The window is held against tops, not cells: a
candidate need only be the highest cell within a window grown by ``cell_window`` of the
slope, since within its whole window may rise the flank of a taller neighbour's crown
(in a dense stand a top two metres from a taller cone's apex), which is not a top.
Crowns: a watershed of the inverted smoothed CHM from the tops (flooding from the highest
level down), within the cells at least ``min_height`` tall.
Then the tops are pruned on the crowns' adjacency graph: a top whose *dynamic* (how far the
smoothed canopy falls from it before a path reaches a higher top) is below ``prominence``
is a bump of the higher crown (a broadleaf's branch clusters, a conifer's side shoot), and a
top lower than ``understory`` times the higher top its crown meets is regeneration under or
beside that tree, not a tree of the stand; either way its crown joins the higher one's. The
window alone cannot do this: a window wide enough to hold one broadleaf crown to one top
merges conifers two metres apart, and one narrow enough to part them splits the broadleaf.

A tree's top and height: given the surface (DSM) and terrain (DTM) on the CHM's grid, the top
is the highest *elevation* of its crown, and its height that elevation less the ground under
its stem (the stem taken as vertical under the top: ``stem_z``); on level ground that is the
crown's highest CHM cell. The CHM is the height of each point above the ground under that
point: on a slope a crown's edge stands higher above the falling ground than its top, so the
CHM's maximum of a rounded crown moves downslope of the top and overstates the height
(Khosravipour et al. 2015, doi:10.1016/j.isprsjprs.2015.02.013); the CHM still finds the
crowns (one maximum each), the DSM places the top. Without them the height is the highest
raw CHM cell of the crown and the position the centre of its top cell.

>>> import numpy as np
>>> from core.io.raster import Raster
>>> xs = np.arange(40) * 0.5
>>> X, Y = np.meshgrid(xs, xs)
>>> bumps = [(5, 5, 20), (14, 12, 15)]
>>> z = sum(h * np.exp(-((X - x) ** 2 + (Y - y) ** 2) / 8) for x, y, h in bumps)
>>> t = detect_trees(Raster(z, x0=0.0, y0=0.0, res=0.5))
>>> np.round(np.column_stack([t["x"], t["y"], t["height"]]), 1).tolist()
[[5.0, 5.0, 20.0], [14.0, 12.0, 15.0]]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from core.io.raster import Raster

__all__ = ["TreeOptions", "detect_trees", "dynamics", "SMOOTH_SPACINGS", "WINDOW_SPACINGS"]


SMOOTH_SPACINGS = 1.07
"""The CHM's smoothing, in mean spacings of the first returns: a CHM is as rough as its
sampling (a cell between returns takes a lower one's height), so the scale that smooths its
pits away grows with the spacing. Set on MixedConifer (0.5 m at its 0.46 m spacing: 4.6
first returns per m²) and carried to other densities in proportion (0.33 m at 10 per m²)."""

WINDOW_SPACINGS = 2.15
"""The local-maximum window's diameter at height 0, in point spacings (1 m on
MixedConifer, as :data:`SMOOTH_SPACINGS`)."""


@dataclass
class TreeOptions(Config):
    """Options of the tree detection."""

    min_height: float = option(2.0, unit="m", range="[0, 100]",
                               help="tops and crowns are at least this tall")
    smooth: float | None = option(None, unit="m", range="[0, 10]",
                                  help="Gaussian sigma of the CHM smoothing before detection "
                                       f"(default: {SMOOTH_SPACINGS} point spacings of the "
                                       "first returns; 0.5 m when not known)")
    window_base: float | None = option(None, unit="m", range="[0, 50]",
                                       help="local-maximum window diameter at height 0 "
                                            f"(default: {WINDOW_SPACINGS} point spacings; "
                                            "1 m when not known)")
    window_slope: float = option(0.1, range="[0, 2]",
                                 help="window diameter grows by this many metres per metre "
                                      "of height")
    prominence: float = option(0.25, unit="m", range="[0, 50]",
                               help="a top is a tree of its own only when the canopy dips "
                                    "at least this much between it and any higher top; "
                                    "else its crown joins the higher one's")
    cell_window: float = option(0.8, range="(0, 1]",
                                help="a cell is a candidate top when it is the highest within "
                                     "a window grown by this share of window_slope, and a top "
                                     "when no higher top lies within its whole window (1: "
                                     "the highest cell within the whole window)")
    understory: float = option(0.3, range="[0, 1]",
                               help="a top lower than this share of the higher top its "
                                    "crown meets is understory, not a tree")


def _disc_max(z: np.ndarray, radius_cells: int) -> np.ndarray:
    from scipy.ndimage import maximum_filter

    r = int(radius_cells)
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return maximum_filter(z, footprint=(xx ** 2 + yy ** 2) <= r * r + 1e-9, mode="nearest")


def _suppress_near_tops(s: np.ndarray, top: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Of the candidate tops, keep each one that no higher kept top lies within its
    window radius (cells, ``radii`` at the top), highest first."""
    from scipy.spatial import cKDTree

    ti, tj = np.nonzero(top)
    order = np.argsort(-s[ti, tj], kind="stable")
    ti, tj = ti[order], tj[order]
    pts = np.column_stack([ti, tj]).astype(np.float64)
    keep = np.zeros(len(ti), bool)
    tree = cKDTree(pts)
    for a in range(len(ti)):
        near = tree.query_ball_point(pts[a], float(radii[ti[a], tj[a]]) + 1e-9)
        if not any(keep[b] and b < a for b in near):
            keep[a] = True
    out = np.zeros_like(top)
    out[ti[keep], tj[keep]] = True
    return out


def _flood(height: np.ndarray, labels: np.ndarray, mask: np.ndarray, *, step: float):
    """Marker-controlled watershed by flooding: the water level falls from the highest
    top in ``step`` metres; at each level every labelled region grows into the unlabelled
    cells of ``mask`` at or above the level that touch it (8-neighbours), until none is
    left. Where two regions meet, the larger label takes the contested cell."""
    from scipy.ndimage import maximum_filter

    lab = labels.copy()
    top = float(height[lab > 0].max())
    bottom = float(height[mask].min()) if np.any(mask) else top
    for level in np.arange(top, bottom - step, -step):
        region = mask & (height >= level)
        while True:
            grow = region & (lab == 0)
            if not np.any(grow):
                break
            near = maximum_filter(lab, size=3, mode="constant")
            new = grow & (near > 0)
            if not np.any(new):
                break
            lab[new] = near[new]
    return lab


def detect_trees(chm: Raster, *, options: TreeOptions | None = None,
                 dsm: Raster | None = None, dtm: Raster | None = None,
                 spacing: float | None = None) -> dict:
    """Tree tops and crowns.

    Parameters
    ----------
    chm : Raster
        Canopy heights, metres.
    options : TreeOptions, optional
    dsm, dtm : Raster, optional
        Highest elevation and ground elevation on the CHM's grid (both or neither): the
        tops are placed on the DSM and the heights measured from the ground at the stem.
    spacing : float, optional
        Mean spacing of the survey's first returns, metres (``1 / sqrt(density)``): the
        smoothing and the window's base when the options leave them to it
        (:data:`SMOOTH_SPACINGS`, :data:`WINDOW_SPACINGS`); without it 0.5 m and 1 m.

    Returns
    -------
    dict
        ``x, y, height, crown_area, stem_z`` (k,) float64 in the raster's coordinates (m,
        m², m; ``stem_z`` the ground's elevation at the stem, NaN without a DTM; sorted by
        the CHM's smoothed top, tallest first) and ``crowns`` (rows, cols) int32: the tree
        (1-based) of each cell, 0 for none.
    """
    if (dsm is None) != (dtm is None):
        raise ValueError("dsm, dtm: expected both or neither")
    for name, r in (("dsm", dsm), ("dtm", dtm)):
        if r is not None and r.values.shape != chm.values.shape:
            raise ValueError(f"{name}: expected the CHM's grid {chm.values.shape}, got "
                             f"{r.values.shape}")
    from scipy.ndimage import gaussian_filter

    o = options or TreeOptions()
    if spacing is not None and not spacing > 0:
        raise ValueError(f"spacing: expected > 0, got {spacing}")
    smooth = o.smooth if o.smooth is not None else (
        0.5 if spacing is None else SMOOTH_SPACINGS * spacing)
    base = o.window_base if o.window_base is not None else (
        1.0 if spacing is None else WINDOW_SPACINGS * spacing)
    raw = np.nan_to_num(chm.values, nan=0.0)
    res = chm.res
    s = gaussian_filter(raw, smooth / res, mode="nearest") if smooth > 0 else raw
    tall = s >= o.min_height
    top = np.zeros(raw.shape, bool)
    # one maximum filter per window radius (in cells) actually needed
    diam = base + o.window_slope * s
    radii = np.maximum(np.round(diam / 2 / res).astype(np.int64), 1)
    # candidates: the highest cell within the window grown by a share of its slope; then
    # no higher top may lie within a candidate's whole window (a higher crown's flank may)
    near = np.maximum(np.round((base + o.cell_window * o.window_slope * s) / 2 / res)
                      .astype(np.int64), 1)
    for r in np.unique(near[tall]):
        sel = tall & (near == r)
        top |= sel & (s >= _disc_max(s, int(r)))
    if o.cell_window < 1.0:
        top = _suppress_near_tops(s, top, radii)
    # a flat plateau gives several equal maxima: keep one per connected plateau
    from scipy.ndimage import label

    lab, n = label(top, structure=np.ones((3, 3)))
    if n == 0:
        empty = np.empty(0)
        return {"x": empty, "y": empty, "height": empty, "crown_area": empty,
                "stem_z": empty, "crowns": np.zeros(raw.shape, np.int32)}
    flat = np.flatnonzero(lab.ravel())
    first = flat[np.unique(lab.ravel()[flat], return_index=True)[1]]
    ti, tj = np.unravel_index(first, raw.shape)
    order = np.argsort(-s[ti, tj], kind="stable")
    ti, tj = ti[order], tj[order]
    k = len(ti)
    crowns = np.zeros(raw.shape, np.int32)
    crowns[ti, tj] = np.arange(1, k + 1)
    crowns = _flood(s, crowns, tall, step=max(0.05, 0.1 * smooth + 0.05))
    if o.prominence > 0 or o.understory > 0:
        keep, crowns = _merge_shallow(s, crowns, k, o.prominence, o.understory)
        ti, tj = ti[keep], tj[keep]
        k = len(ti)
    area = np.bincount(crowns.ravel(), minlength=k + 1)[1:] * res * res
    if dsm is not None:
        ai, aj = _highest(dsm.values, crowns, ti, tj)
        stem_z = dtm.values[ai, aj].astype(np.float64)
        height = dsm.values[ai, aj] - stem_z
        ti, tj = ai, aj
    else:
        height = np.zeros(k + 1)
        np.maximum.at(height, crowns.ravel(), raw.ravel())
        height = np.maximum(height[1:], raw[ti, tj])
        stem_z = np.full(k, np.nan)
    return {"x": chm.x0 + tj * res, "y": chm.y0 + ti * res, "height": height,
            "crown_area": area.astype(np.float64), "stem_z": stem_z,
            "crowns": crowns.astype(np.int32)}


def _saddles(s: np.ndarray, crowns: np.ndarray):
    """The pass between every two touching crowns (8-neighbours): ``(a, b, level)``, the
    highest of ``min(s)`` over the cell pairs where crown ``a`` meets crown ``b`` (a < b,
    1-based)."""
    a_all, b_all, lv_all = [], [], []
    r, c = s.shape
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        i0, i1 = 0, r - di
        j0, j1 = max(0, -dj), c - max(0, dj)
        la = crowns[i0:i1, j0:j1]
        lb = crowns[i0 + di:i1 + di, j0 + dj:j1 + dj]
        sel = (la > 0) & (lb > 0) & (la != lb)
        if not np.any(sel):
            continue
        lv = np.minimum(s[i0:i1, j0:j1][sel], s[i0 + di:i1 + di, j0 + dj:j1 + dj][sel])
        a, b = la[sel], lb[sel]
        a_all.append(np.minimum(a, b))
        b_all.append(np.maximum(a, b))
        lv_all.append(lv)
    if not a_all:
        return np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0)
    a, b, lv = np.concatenate(a_all), np.concatenate(b_all), np.concatenate(lv_all)
    key = a.astype(np.int64) * (int(crowns.max()) + 1) + b
    order = np.lexsort((lv, key))          # by pair, then level: the last of each is highest
    last = np.r_[key[order][1:] != key[order][:-1], True]
    o = order[last]
    return a[o].astype(np.int64), b[o].astype(np.int64), lv[o]


def dynamics(s: np.ndarray, crowns: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Each top's dynamic: how far the canopy must fall from it before a path reaches a
    higher top (its peak less the highest pass to a higher crown; Grimaud 1992; the
    h-maxima of Soille 2003 keep the maxima of dynamic at least h), and the crown of that
    higher top. Crowns ``1..k`` sorted by top height, tallest first; the tallest of each
    group of touching crowns has an infinite dynamic and itself as its higher crown.

    The passes are taken highest first (Kruskal's order on the crowns' adjacency graph):
    when a pass joins two groups, the lower group's top has met a higher one at that level.
    Returns ``(dynamic (k,), higher (k,) 1-based)``."""
    peak = np.zeros(k + 1)
    np.maximum.at(peak, crowns.ravel(), s.ravel())
    a, b, lv = _saddles(s, crowns)
    parent = np.arange(k + 1)

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    owner = np.arange(k + 1)   # each group's highest top (its lowest label)
    dyn = np.full(k + 1, np.inf)
    higher = np.arange(k + 1)
    for i in np.argsort(-lv, kind="stable"):
        ra, rb = find(a[i]), find(b[i])
        if ra == rb:
            continue
        ha, hb = owner[ra], owner[rb]
        hi, lo = (ha, hb) if ha < hb else (hb, ha)   # label order is height order
        dyn[lo] = peak[lo] - lv[i]
        higher[lo] = hi
        parent[rb] = ra
        owner[ra] = hi
    return dyn[1:], higher[1:]


def _merge_shallow(s: np.ndarray, crowns: np.ndarray, k: int, prominence: float,
                   under: float):
    """Join each top of dynamic (:func:`dynamics`) below ``prominence``, or lower than
    ``under`` times the higher top it meets, to the crown of that higher top (or where that
    one went). Returns the tops kept (k,) bool and the crowns relabelled ``1..kept`` in the
    same order."""
    dyn, higher = dynamics(s, crowns, k)
    peak = np.zeros(k + 1)
    np.maximum.at(peak, crowns.ravel(), s.ravel())
    keep = np.r_[True, (dyn >= prominence)
                 & ((peak[1:] >= under * peak[higher]) | ~np.isfinite(dyn))]
    into = np.r_[0, higher]
    for t in range(1, k + 1):          # higher labels come first: follow the chain down
        c = t
        while not keep[c]:
            c = into[c]
        into[t] = c
    kept = keep[1:]
    new = np.zeros(k + 1, np.int64)
    new[1:][kept] = np.arange(1, int(kept.sum()) + 1)
    return kept, new[into][crowns].astype(np.int32)


def _highest(z: np.ndarray, crowns: np.ndarray, ti, tj) -> tuple:
    """For each crown ``k`` (1-based in ``crowns``) its cell of highest ``z``:
    ``(rows, cols)`` (k,), the top ``(ti, tj)`` for a crown of no cell."""
    ci, cj = np.nonzero(crowns)
    lab = crowns[ci, cj] - 1
    order = np.lexsort((z[ci, cj], lab))  # by crown, then by z: the last of each is highest
    last = np.r_[lab[order][1:] != lab[order][:-1], True]
    ai, aj = np.array(ti, np.int64), np.array(tj, np.int64)
    ai[lab[order][last]] = ci[order][last]
    aj[lab[order][last]] = cj[order][last]
    return ai, aj
