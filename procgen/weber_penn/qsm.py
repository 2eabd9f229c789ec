"""A grown tree's woody skeleton as a QSM: cylinders cut at every branch's base.

Each stem's centreline is cut at its own points and wherever a child leaves it, so a
cylinder ends at every fork and the parent of a branch's first cylinder is the cylinder
that ends where it starts (as TreeQSM links them). A cylinder's radius is the stem's just
past its start; between two centreline points the stem's own term is held and the pipes
of the children passed are taken off, so the radii keep the tree's Leonardo exponent at
every fork. The trunk's flare widens its lowest cylinders.
"""

from __future__ import annotations

import numpy as np

from core.io.qsm import QSM, check_qsm
from procgen.weber_penn.growth import Tree
from procgen.weber_penn.shapes import flare_factor

__all__ = ["tree_qsm"]

_ROUND = 7  # breakpoints closer than 1e-7 m are one


def tree_qsm(tree: Tree) -> QSM:
    """The cylinders of ``tree``'s skeleton (ids from 1; see :mod:`core.io.qsm`)."""
    sk = tree.skeleton
    delta = tree.params.model["leonardo_exponent"]
    stem_of = sk.stem_of_point()
    n_stems = sk.n_stems
    smax = float(max(sk.arc.max(), sk.attach.max())) + 1.0
    arc = np.round(sk.arc, _ROUND)
    kids = np.flatnonzero(sk.parent >= 0)
    katt = np.round(sk.attach[kids], _ROUND)
    kpar = sk.parent[kids]
    kpow = sk.radius[sk.ptr[kids]] ** delta
    pkey = stem_of * smax + arc                       # sorted: stems in order, arcs rising
    ckey = kpar * smax + katt
    corder = np.argsort(ckey, kind="stable")
    ckey_s, cpow = ckey[corder], np.concatenate([[0.0], np.cumsum(kpow[corder])])
    # breakpoints: the points and the children's bases
    bstem = np.concatenate([stem_of, kpar])
    bs = np.concatenate([arc, katt])
    bkey = bstem * smax + bs
    order = np.lexsort((bs, bstem))
    bstem, bs, bkey = bstem[order], bs[order], bkey[order]
    keep = np.ones(len(bs), bool)
    keep[1:] = (bstem[1:] != bstem[:-1]) | (bs[1:] - bs[:-1] > 10.0 ** -_ROUND)
    bstem, bs, bkey = bstem[keep], bs[keep], bkey[keep]
    # the point at or before each breakpoint, the position and the radius just past it
    ip = np.clip(np.searchsorted(pkey, bkey + 1e-12, side="right") - 1, 0, len(pkey) - 1)
    t = bs - arc[ip]
    nxt = np.minimum(ip + 1, len(pkey) - 1)
    d = np.where((stem_of[nxt] == stem_of[ip])[:, None], sk.points[nxt] - sk.points[ip], 0.0)
    seg = np.where(stem_of[nxt] == stem_of[ip], arc[nxt] - arc[ip], 1.0)
    pos = sk.points[ip] + d * (t / np.maximum(seg, 1e-12))[:, None]
    passed = (cpow[np.searchsorted(ckey_s, bkey + 1e-12, side="right")]
              - cpow[np.searchsorted(ckey_s, pkey[ip] + 1e-12, side="right")])
    rpow = np.clip(sk.radius[ip] ** delta - passed, 0, None)
    rad = rpow ** (1.0 / delta)
    # cylinders between consecutive breakpoints of a stem
    same = bstem[1:] == bstem[:-1]
    c0 = np.flatnonzero(same)
    start, end = pos[c0], pos[c0 + 1]
    vec = end - start
    length = np.linalg.norm(vec, axis=1)
    axis = vec / np.maximum(length, 1e-12)[:, None]
    cstem = bstem[c0]
    radius = rad[c0]
    trunk = (sk.level[cstem] == 0) & ~sk.clone[cstem]
    z = bs[c0] / sk.stem_length[cstem]
    radius = np.where(trunk, radius * flare_factor(z, tree.params["Flare"]), radius)
    n = len(c0)
    ids = np.arange(1, n + 1)
    first = np.ones(n, bool)
    first[1:] = cstem[1:] != cstem[:-1]
    last = np.ones(n, bool)
    last[:-1] = cstem[1:] != cstem[:-1]
    parent = np.where(first, 0, ids - 1)
    extension = np.where(last, 0, ids + 1)
    # a stem's first cylinder hangs from the parent's cylinder ending at its base
    end_key = bkey[c0 + 1]
    fs = np.flatnonzero(first)
    par_stem = sk.parent[cstem[fs]]
    has = par_stem >= 0
    want = par_stem * smax + np.round(sk.attach[cstem[fs]], _ROUND)
    j = np.searchsorted(end_key, want - 10.0 ** -(_ROUND - 1))
    j = np.clip(j, 0, n - 1)
    ok = has & (cstem[j] == par_stem)
    stem_first = np.full(n_stems, -1)
    stem_first[cstem[fs]] = fs
    fallback = stem_first[np.maximum(par_stem, 0)]
    link = np.where(ok, j, fallback)
    parent[fs] = np.where(has, ids[np.maximum(link, 0)], 0)
    # further trunks (0Branches > 1) hang from the first trunk's base
    roots = fs[~has]
    if len(roots) > 1:
        parent[roots[1:]] = ids[roots[0]]
    qsm = QSM(ids, parent, extension, cstem + 1, sk.level[cstem].astype(int), start, axis,
              length, radius)
    return check_qsm(qsm)
