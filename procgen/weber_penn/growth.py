"""Weber & Penn's tree generator: stems level by level, then leaves, as a skeleton.

Follows Weber and Penn, "Creation and rendering of realistic trees" (SIGGRAPH 1995), §4:
the trunk (level 0) and up to three levels of branches are grown as stems of ``CurveRes``
segments; each segment turns about the stem's own x axis by ``Curve / CurveRes`` (the
first half by ``Curve``, the second by ``CurveBack`` when that is set) plus a random
``±CurveV / CurveRes`` (a negative ``CurveV`` makes the stem a helix leaning ``|CurveV|``
off its axis); stems of level 2 and up turn toward (``AttractionUp`` > 0) or away from
the sky. ``SegSplits`` (error-diffused, ``0BaseSplits`` at the trunk's first segment)
splits a stem into clones that lean ``SplitAngle ± SplitAngleV`` apart (the trunk's less
its declination). Children leave a stem evenly (``BranchDist`` 1) or in whorls at segment
ends (``BranchDist`` 0), turned about the parent by ``Rotate`` (negative: two ranks,
alternating) and tilted off it by ``DownAngle`` (a negative ``DownAngleV`` varies it from
the crown base to the top); their count and length follow the paper's formulas (the
first level by the crown ``Shape``). ``PruneRatio`` shortens the stems that leave the
envelope (shape 8). Leaves are the children of the last level, ``Leaves`` per stem scaled
by ``LeafDistrib`` (negative: a fan at the tip).

Radii. The paper's radius (``Ratio``, ``RatioPower``, ``Taper``) is each stem's own
term; the radius along a stem adds the pipes of everything beyond, so at every fork
``d**D = sum d_i**D`` with ``D = leonardo_exponent`` (Leonardo's rule; Eloy 2011); the
whole tree is then scaled so the trunk's base radius follows the species' height-diameter
law, ``Scale * Ratio * 0Scale * (height / Scale) ** (1 / b)`` (the paper's radius at the
species' own height ``Scale``).

>>> import numpy as np
>>> from procgen.weber_penn.params import load_species
>>> t = grow(load_species("quaking_aspen"), height=8.0, rng=np.random.default_rng(1))
>>> round(float(t.skeleton.points[:, 2].max()), 6), t.skeleton.n_stems > 100
(8.0, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.validate import check_rng
from procgen.weber_penn.params import TreeParams
from procgen.weber_penn.shapes import inside_envelope, shape_ratio, taper_radius

__all__ = ["Skeleton", "Leaves", "Tree", "grow"]

UP = np.array([0.0, 0.0, 1.0])
TRUNK_POINTS = 64  # the trunk's centreline has at least this many points
OWN_PIPE = 0.35  # share of a non-terminal stem's own (W&P) radius in its pipe


@dataclass
class Skeleton:
    """The woody skeleton: stems as polylines with radii.

    Attributes
    ----------
    level : (s,) int   the stem's level (0 the trunk); a split clone keeps its stem's level
    parent : (s,) int  the stem it grows from (-1 for a trunk)
    attach : (s,) float  arc length along the parent where it starts (m)
    clone : (s,) bool  a clone from a split (it continues its parent's stem)
    ptr : (s + 1,) int  stem i's points are ``points[ptr[i]:ptr[i + 1]]``
    points : (n, 3) float  centreline points (m), stem by stem
    arc : (n,) float  arc length of each point along its stem (m)
    radius : (n,) float  the radius just past each point (m)
    xaxis, yaxis : (n, 3) float  the stem's frame at each point (for the tube's rings)
    stem_length : (s,) float  the paper's length of the stem (m)
    """

    level: np.ndarray
    parent: np.ndarray
    attach: np.ndarray
    clone: np.ndarray
    ptr: np.ndarray
    points: np.ndarray
    arc: np.ndarray
    radius: np.ndarray
    xaxis: np.ndarray
    yaxis: np.ndarray
    stem_length: np.ndarray

    @property
    def n_stems(self) -> int:
        return len(self.level)

    def stem_of_point(self) -> np.ndarray:
        """(n,) int: the stem of each point."""
        return np.repeat(np.arange(self.n_stems), np.diff(self.ptr))


@dataclass
class Leaves:
    """Leaves: ``position`` (k, 3) the blade's base, ``axis`` (k, 3) along the blade,
    ``normal`` (k, 3) its face, ``length``/``width`` (k,) metres, ``stem`` (k,) the stem it
    hangs from."""

    position: np.ndarray
    axis: np.ndarray
    normal: np.ndarray
    length: np.ndarray
    width: np.ndarray
    stem: np.ndarray

    def __len__(self) -> int:
        return len(self.position)


@dataclass
class Tree:
    """A grown tree: its ``skeleton``, ``leaves``, the ``params`` it came from and its
    ``height`` (m, the top of the skeleton)."""

    params: TreeParams
    skeleton: Skeleton
    leaves: Leaves
    height: float


# ---------------------------------------------------------------- rotations (vectorised)

def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(k, 3, 3) rotations by ``angle`` (k,) radians about unit ``axis`` (k, 3)."""
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    C = 1 - c
    return np.stack([np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
                     np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
                     np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1)], 1)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 1e-12, n, 1.0)


def _child_frames(pframe: np.ndarray, azimuth: np.ndarray, down: np.ndarray) -> np.ndarray:
    """Frames (k, 3, 3; columns x, y, z) of children turned ``azimuth`` about the parent's
    z and tilted ``down`` off it (radians); y points back toward the parent's axis."""
    px, py, pz = pframe[:, :, 0], pframe[:, :, 1], pframe[:, :, 2]
    a = np.cos(azimuth)[:, None] * px + np.sin(azimuth)[:, None] * py
    c, s = np.cos(down)[:, None], np.sin(down)[:, None]
    z = c * pz + s * a
    y = _unit(s * pz - c * a)
    x = np.cross(y, z)
    return np.stack([x, y, z], -1)


# ---------------------------------------------------------------- one level of stems

@dataclass
class _Rows:
    """A level's stems (and their clones) as rows of equal segment count."""

    P: np.ndarray        # (k, res + 1, 3), NaN before a clone's start
    F: np.ndarray        # (k, res, 3, 3) segment frames
    j0: np.ndarray       # (k,) first segment
    length: np.ndarray   # (k,) the stem's full length
    seg: np.ndarray      # (k,) segment length
    r0: np.ndarray       # (k,) the paper's base radius
    parent: np.ndarray   # (k,) parent row in the previous level, or -1
    attach: np.ndarray   # (k,) full offset on the parent (clones: -1)
    split_of: np.ndarray  # (k,) the row of this level it split from, or -1
    group: np.ndarray    # (k,) the original stem (for pruning)


def _curve_angles(lv: dict, res: int, j: int, k: int, rng) -> np.ndarray:
    if lv["CurveBack"] == 0:
        base = lv["Curve"] / res
    else:
        half = max(res / 2.0, 1.0)
        base = (lv["Curve"] if j < res / 2.0 else lv["CurveBack"]) / half
    return np.radians(base + rng.uniform(-1, 1, k) * lv["CurveV"] / res)


def _grow_rows(origin, frame, length, r0, parent, attach, *, lv: dict, level: int,
               p: TreeParams, rng) -> _Rows:
    res = int(lv["CurveRes"])
    k = len(origin)
    P = np.full((k, res + 1, 3), np.nan)
    P[:, 0] = origin
    F = np.empty((k, res, 3, 3))
    seg = length / res
    j0 = np.zeros(k, int)
    err = np.zeros(k)
    split_of = np.full(k, -1)
    group = np.arange(k)
    frame = frame.copy()
    z0 = frame[:, :, 2].copy()
    helix = lv["CurveV"] < 0
    for j in range(res):
        k = len(frame)
        act = j0 <= j
        if helix:
            tilt = np.where(j0 == j, math.radians(-lv["CurveV"]), 0.0)
            R = _rot(frame[:, :, 0], tilt)
            spin = np.where(j0 < j, 2 * math.pi / max(res, 4), 0.0)
            R = _rot(z0, spin) @ R
        else:
            R = _rot(frame[:, :, 0], _curve_angles(lv, res, j, k, rng))
        if level >= 2 and p["AttractionUp"] != 0:
            z = (R @ frame)[:, :, 2]
            decl = np.arccos(np.clip(z[:, 2], -1, 1))
            ang = p["AttractionUp"] * decl / res
            ang = np.clip(ang, -(np.pi - decl), decl)
            axis = np.cross(z, UP)
            ok = np.linalg.norm(axis, axis=1) > 1e-9
            R = np.where((ok & act)[:, None, None],
                         _rot(_unit(axis), np.where(ok, ang, 0.0)) @ R, R)
        frame = np.where(act[:, None, None], R @ frame, frame)
        F[:, j] = frame
        P[:, j + 1] = np.where(act[:, None], P[:, j] + seg[:, None] * frame[:, :, 2], np.nan)
        # splits at the end of this segment
        if j == res - 1:
            continue
        if level == 0 and j == 0 and p["0BaseSplits"] > 0:
            n_split = np.where(act, p["0BaseSplits"], 0)
        elif lv["SegSplits"] > 0:
            eff = lv["SegSplits"] + err
            n_split = np.where(act, np.floor(eff + 0.5), 0).astype(int)
            err = np.where(act, eff - n_split, err)
        else:
            continue
        rows = np.flatnonzero(n_split > 0)
        if not len(rows):
            continue
        ns = n_split[rows]
        angle = lv["SplitAngle"] + rng.uniform(-1, 1, len(rows)) * lv["SplitAngleV"]
        if level == 0:
            decl = np.degrees(np.arccos(np.clip(frame[rows, 2, 2], -1, 1)))
            angle = angle - decl
        angle = np.radians(np.clip(angle, 0, None))
        psi0 = rng.uniform(0, 2 * np.pi, len(rows))
        # the stem itself leans to psi0, its clones to psi0 + 2 pi i / (n + 1)
        rep = np.repeat(np.arange(len(rows)), ns + 1)
        idx = np.concatenate([np.arange(n + 1) for n in ns])
        psi = psi0[rep] + 2 * np.pi * idx / (ns[rep] + 1)
        fr = frame[rows[rep]]
        lean = np.cos(psi)[:, None] * fr[:, :, 0] + np.sin(psi)[:, None] * fr[:, :, 1]
        axis = _unit(np.cross(fr[:, :, 2], lean))
        new_frames = _rot(axis, angle[rep]) @ fr
        first = idx == 0
        frame[rows] = new_frames[first]
        src = rows[rep[~first]]
        m = len(src)
        if not m:
            continue
        Pc = np.full((m, res + 1, 3), np.nan)
        Pc[:, j + 1] = P[src, j + 1]
        P = np.concatenate([P, Pc])
        F = np.concatenate([F, np.full((m, res, 3, 3), np.nan)])
        frame = np.concatenate([frame, new_frames[~first]])
        z0 = np.concatenate([z0, new_frames[~first][:, :, 2]])
        j0 = np.concatenate([j0, np.full(m, j + 1)])
        err = np.concatenate([err, err[src]])
        seg = np.concatenate([seg, seg[src]])
        length = np.concatenate([length, length[src]])
        r0 = np.concatenate([r0, r0[src]])
        parent = np.concatenate([parent, parent[src]])
        attach = np.concatenate([attach, np.full(m, -1.0)])
        split_of = np.concatenate([split_of, src])
        group = np.concatenate([group, group[src]])
    return _Rows(P, F, j0, length, seg, r0, parent, attach, split_of, group)


# ---------------------------------------------------------------- children of a level

def _round_random(x: np.ndarray, rng) -> np.ndarray:
    x = np.clip(x, 0, None)
    base = np.floor(x)
    return (base + (rng.random(len(x)) < x - base)).astype(int)


def _group_share(rows: _Rows) -> np.ndarray:
    """Each row's share of its stem's children: a stem split into clones spreads the
    children it would have had over them, by the segments each carries."""
    res = rows.F.shape[1]
    active = (res - rows.j0).astype(float)
    total = np.zeros(int(rows.group.max()) + 1 if len(rows.group) else 0)
    np.add.at(total, rows.group, active)
    return active / np.maximum(total[rows.group], 1e-12)


def _placements(rows: _Rows, counts: np.ndarray, lo: np.ndarray, lv: dict, rng):
    """Where a level's children (or leaves) leave ``rows``: (row, full offset, position,
    parent frame, azimuth) for ``counts`` per row spread over [lo, stem end]."""
    res = rows.F.shape[1]
    row = np.repeat(np.arange(len(counts)), counts)
    if not len(row):
        return row, np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0)
    start = np.maximum(lo, rows.j0 * rows.seg)[row]
    span = np.clip(rows.length[row] - start, 0, None)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    i = np.arange(len(row)) - first[row]
    m = counts[row]
    even = start + (i + 0.5) / m * span
    seg = rows.seg[row]
    whorl_idx = np.minimum(np.ceil(even / seg - 1e-9), res).astype(int)
    whorl = np.maximum(whorl_idx * seg, start)
    d = lv["BranchDist"]
    off = np.minimum(whorl + d * (even - whorl), rows.length[row] * (1 - 1e-9))
    rot, rotv = lv["Rotate"], lv["RotateV"]
    noise = rng.uniform(-1, 1, len(row)) * rotv
    if d < 0.5:  # whorls: spread evenly about the stem, each whorl turned by Rotate
        key = row * (res + 2) + whorl_idx
        _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
        rank = np.arange(len(key)) - np.searchsorted(key, key)  # keys are sorted
        az = whorl_idx * rot + 360.0 * rank / cnt[inv] + noise
    elif rot >= 0:
        az = rng.uniform(0, 360, len(counts))[row] + i * rot + noise
    else:  # two ranks: the blade plane leans 180 + Rotate off the side, alternating
        c = 180.0 + rot
        az = np.where(i % 2 == 0, c, 180.0 - c) + noise
    js = np.clip(np.floor(off / seg).astype(int), rows.j0[row], res - 1)
    t = off - js * seg
    pf = rows.F[row, js]
    pos = rows.P[row, js] + t[:, None] * pf[:, :, 2]
    return row, off, pos, pf, np.radians(az)


def _down_angles(lv: dict, off, length_p, base_p, rng):
    if lv["DownAngleV"] >= 0:
        return np.radians(lv["DownAngle"] + rng.uniform(-1, 1, len(off)) * lv["DownAngleV"])
    ratio = np.clip((length_p - off) / np.maximum(length_p - base_p, 1e-9), 0, 1)
    return np.radians(lv["DownAngle"] + lv["DownAngleV"] * (1 - 2 * shape_ratio(0, ratio)))


@dataclass
class _Level:
    rows: _Rows
    level: int
    base: float  # where children may start on these stems (the trunk's crown base)
    offset_in_parent: np.ndarray  # (k,) the stem's own full offset on its parent (clones: its
    #                                original's)
    parent_length: np.ndarray     # (k,) its parent's length


def _children(prev: _Level, n: int, p: TreeParams, trunk_len: float, rng):
    """Counts, placements, lengths and radii of level ``n``'s stems on ``prev``."""
    lv = p.levels[n]
    rows = prev.rows
    active = _group_share(rows)
    if n == 1:
        per = lv["Branches"] * active
        lo = np.full(len(rows.j0), prev.base)
    elif n == 2:
        lmax = max(p.levels[1]["Length"] + p.levels[1]["LengthV"], 1e-9)
        per = lv["Branches"] * (0.2 + 0.8 * (rows.length / prev.parent_length) / lmax) * active
        lo = np.zeros(len(rows.j0))
    else:
        per = lv["Branches"] * (1.0 - 0.5 * prev.offset_in_parent / prev.parent_length) * active
        lo = np.zeros(len(rows.j0))
    counts = _round_random(per, rng)
    row, off, pos, pf, az = _placements(rows, counts, lo, lv, rng)
    length_p = rows.length[row]
    down = _down_angles(lv, off, length_p, prev.base if n == 1 else 0.0, rng)
    frames = _child_frames(pf, az, down)
    lmax = lv["Length"] + rng.uniform(-1, 1, len(row)) * lv["LengthV"]
    if n == 1:
        ratio = (length_p - off) / max(length_p.max() - prev.base, 1e-9)
        shape = 8 if p["PruneRatio"] > 0 and p["Shape"] == 8 else p["Shape"]
        length = trunk_len * lmax * shape_ratio(shape, np.clip(ratio, 0, 1), prune=p.tree)
    else:
        length = lmax * (length_p - 0.6 * off)
    length = np.clip(length, 0, None)
    r_parent = taper_radius(rows.r0[row], length_p, off / length_p,
                            p.levels[n - 1]["Taper"])
    r0 = np.minimum(rows.r0[row] * (length / np.maximum(length_p, 1e-12)) ** p["RatioPower"],
                    r_parent)
    keep = (length > 1e-6) & (r0 > 0)
    return (pos[keep], frames[keep], length[keep], r0[keep], row[keep], off[keep],
            length_p[keep])


def _grow_level(prev: _Level, n: int, p: TreeParams, trunk_len: float, scale: float, rng):
    pos, frames, length, r0, row, off, length_p = _children(prev, n, p, trunk_len, rng)
    lv = p.levels[n]
    seed = int(rng.integers(2 ** 62))
    rows = _grow_rows(pos, frames, length, r0, row, off, lv=lv, level=n, p=p,
                      rng=np.random.default_rng(seed))
    if p["PruneRatio"] > 0 and len(length):
        for _ in range(2):
            rows = _prune(rows, pos, frames, length, r0, row, off, lv=lv, n=n, p=p,
                          scale=scale, seed=seed)
    return _Level(rows, n, 0.0, off[rows.group], length_p[rows.group])


def _prune(rows: _Rows, pos, frames, length, r0, row, off, *, lv, n, p, scale, seed):
    """Shorten the stems leaving the envelope (the paper's pruning, ``PruneRatio``)."""
    res = rows.F.shape[1]
    inside = inside_envelope(rows.P, scale=scale, base_size=p["BaseSize"], prune=p.tree)
    inside |= np.isnan(rows.P[..., 0])
    frac = np.ones(len(rows.j0))
    outside = ~inside
    bad = outside.any(1)
    first_out = np.argmax(outside, 1)
    frac[bad] = np.maximum(first_out[bad] - 1, 0) / res
    # a stem's group keeps the smallest fraction of its clones
    gfrac = np.ones(len(length))
    np.minimum.at(gfrac, rows.group, frac)
    cur = rows.length[:len(length)]
    new_len = cur * (1 - p["PruneRatio"] * (1 - gfrac))
    new_len = np.maximum(new_len, cur * 0.05)
    return _grow_rows(pos, frames, new_len, r0, row, off, lv=lv, level=n, p=p,
                      rng=np.random.default_rng(seed))


# ---------------------------------------------------------------- the whole tree

def _trunk(p: TreeParams, trunk_len: float, r0: float, rng) -> _Level:
    lv = p.levels[0]
    k = max(int(lv["Branches"]), 1)
    az = np.radians(np.arange(k) * 360.0 / k + rng.uniform(-1, 1, k) * lv["RotateV"])
    down = np.radians(lv["DownAngle"] + rng.uniform(-1, 1, k) * lv["DownAngleV"]) * (k > 1)
    frames = _child_frames(np.repeat(np.eye(3)[None], k, 0), az, down)
    length = np.full(k, trunk_len)
    rows = _grow_rows(np.zeros((k, 3)), frames, length, np.full(k, r0), np.full(k, -1),
                      np.zeros(k), lv=lv, level=0, p=p, rng=rng)
    return _Level(rows, 0, p["BaseSize"] * trunk_len, np.zeros(len(rows.j0)),
                  np.full(len(rows.j0), trunk_len))


def _leaves(last: _Level, p: TreeParams, rng) -> Leaves:
    n_leaf = min(p["Levels"], 3)
    lv = p.levels[n_leaf]
    rows = last.rows
    active = _group_share(rows)
    quality = p["LeafQuality"]
    leaves = p["Leaves"]
    if p["Levels"] == 1:
        per = np.full(len(rows.j0), abs(leaves) * quality)
        lo = np.full(len(rows.j0), last.base)
    else:
        ratio = np.clip(last.offset_in_parent / last.parent_length, 0, 1)
        per = abs(leaves) * shape_ratio(p["LeafDistrib"], ratio, prune=p.tree) * quality * active
        lo = np.zeros(len(rows.j0))
    counts = _round_random(per, rng)
    if leaves < 0:  # a fan at the stem's tip
        lo = rows.length * (1 - 1e-6)
    row, off, pos, pf, az = _placements(rows, counts, lo, lv, rng)
    down = _down_angles(lv, off, rows.length[row], 0.0, rng)
    if leaves < 0:
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        i = np.arange(len(row)) - first[row]
        az = np.radians(np.where(counts[row] > 1, -60 + 120 * i / np.maximum(counts[row] - 1, 1),
                                 0.0))
    fr = _child_frames(pf, az, down)
    axis, normal = fr[:, :, 2], fr[:, :, 1]
    normal = np.where((normal[:, 2] < 0)[:, None], -normal, normal)
    bend = p["LeafBend"]
    normal = _unit((1 - bend) * normal + bend * UP)
    axis = _unit(axis - (axis * normal).sum(1, keepdims=True) * normal)
    length = np.full(len(row), p["LeafScale"] / math.sqrt(quality))
    length *= 1 + 0.15 * rng.uniform(-1, 1, len(row))
    width = length * p["LeafScaleX"]
    pos = pos + axis * (p["LeafStemLen"] * length)[:, None]
    return Leaves(pos, axis, normal, length, width, row)


def _pipe_radii(parent, attach, arc, ptr, own, delta):
    """Radius at each point: ``(own(s)**D + sum over stems attached beyond s of r**D)**(1/D)``,
    computed from the tips down (stems in batches of equal height above the tips)."""
    n_stems = len(parent)
    stem_of = np.repeat(np.arange(n_stems), np.diff(ptr))
    depth = np.zeros(n_stems, int)
    has = parent >= 0
    while True:  # a stem's depth: one more than its deepest child's
        new = depth.copy()
        np.maximum.at(new, parent[has], depth[has] + 1)
        if np.array_equal(new, depth):
            break
        depth = new
    base_pow = np.zeros(n_stems)
    out = np.zeros(len(arc))
    smax = float(arc.max()) + 1.0
    pt_depth = depth[stem_of]
    for d in range(depth.max() + 1):
        batch = np.flatnonzero(depth == d)
        kids = np.flatnonzero(has & (depth[np.where(has, parent, 0)] == d))
        pts = np.flatnonzero(pt_depth == d)
        total = own[pts] ** delta
        if len(kids):
            kkey = parent[kids] * smax + attach[kids]
            order = np.argsort(kkey, kind="stable")
            kkey, kpow = kkey[order], base_pow[kids][order]
            csum = np.concatenate([[0.0], np.cumsum(kpow)])
            beyond = np.searchsorted(kkey, stem_of[pts] * smax + arc[pts], side="right")
            end = np.searchsorted(kkey, stem_of[pts] * smax + (smax - 0.5), side="right")
            total = total + csum[end] - csum[beyond]
        out[pts] = total ** (1.0 / delta)
        base_pow[batch] = total[np.searchsorted(pts, ptr[batch])]
    return out


def _refine(rows: _Rows, points: int) -> _Rows:
    """The trunk with each segment cut into equal parts, so it has at least ``points``
    points (the flare, the lobes and a periodic taper need them; the shape is the same)."""
    res = rows.F.shape[1]
    m = max(1, math.ceil(points / res))
    if m == 1:
        return rows
    q = np.arange(m) / m
    seg = rows.seg / m
    z = rows.F[:, :, :, 2]                                       # (k, res, 3)
    P = rows.P[:, :-1, None, :] + (q[None, None, :, None] * rows.seg[:, None, None, None]
                                   * z[:, :, None, :])
    P = np.concatenate([P.reshape(len(seg), res * m, 3), rows.P[:, -1:]], 1)
    F = np.repeat(rows.F, m, axis=1)
    return _Rows(P, F, rows.j0 * m, rows.length, seg, rows.r0, rows.parent, rows.attach,
                 rows.split_of, rows.group)


def _assemble(levels: list[_Level], p: TreeParams) -> Skeleton:
    """Flatten the levels' rows into stems (dropping a clone's NaN head) with global ids."""
    lvl, par, att, clone, pts, xs, ys, arcs, counts, slen, own_r = ([] for _ in range(11))
    first = 0
    prev_first = 0
    for L in levels:
        rows = L.rows
        k, res = len(rows.j0), rows.F.shape[1]
        j = np.arange(res + 1)
        valid = j[None, :] >= rows.j0[:, None]
        F = np.concatenate([rows.F, rows.F[:, -1:]], 1)
        pts.append(rows.P[valid])
        xs.append(F[..., 0][valid])
        ys.append(F[..., 1][valid])
        arc = (j[None, :] - rows.j0[:, None]) * rows.seg[:, None]
        arcs.append(arc[valid])
        counts.append(res + 1 - rows.j0)
        is_clone = rows.split_of >= 0
        src = np.where(is_clone, rows.split_of, 0)
        if L.level > 0:
            prow = levels[L.level - 1].rows
            pj = np.where(is_clone, 0, rows.parent)
            child_att = rows.attach - prow.j0[pj] * prow.seg[pj]
            child_par = prev_first + rows.parent
        else:
            child_att = np.zeros(k)
            child_par = np.full(k, -1)
        par.append(np.where(is_clone, first + src, child_par))
        att.append(np.where(is_clone, (rows.j0 - rows.j0[src]) * rows.seg, child_att))
        clone.append(is_clone)
        lvl.append(np.full(k, L.level))
        slen.append(rows.length)
        z = np.clip((arc + rows.j0[:, None] * rows.seg[:, None]) / rows.length[:, None], 0, 1)
        own = taper_radius(rows.r0[:, None], rows.length[:, None], z,
                           p.levels[L.level]["Taper"])
        terminal = L.level == len(levels) - 1
        own_r.append((own * (1.0 if terminal else OWN_PIPE))[valid])
        prev_first = first
        first += k
    ptr = np.concatenate([[0], np.cumsum(np.concatenate(counts))])
    level, parent = np.concatenate(lvl), np.concatenate(par)
    attach, arc = np.concatenate(att), np.concatenate(arcs)
    radius = _pipe_radii(parent, attach, arc, ptr, np.concatenate(own_r),
                         p.model["leonardo_exponent"])
    return Skeleton(level, parent, attach, np.concatenate(clone), ptr, np.concatenate(pts),
                    arc, radius, np.concatenate(xs), np.concatenate(ys), np.concatenate(slen))


def grow(params: TreeParams, *, height: float | None = None,
         rng: np.random.Generator) -> Tree:
    """Grow one tree of ``params``' species.

    Parameters
    ----------
    params : TreeParams
    height : float, optional
        Height of the skeleton's top in metres; default the species' ``Scale ± ScaleV``.
    rng : numpy.random.Generator

    Returns
    -------
    Tree
    """
    rng = check_rng(rng)
    if height is not None and not (math.isfinite(height) and height > 0):
        raise ValueError(f"height: expected a positive length in metres, got {height!r}")
    lv0 = params.levels[0]
    if height is None:
        scale = params["Scale"] + rng.uniform(-1, 1) * params["ScaleV"]
        scale = max(scale, 0.05 * params["Scale"])
    else:
        scale = height / max(lv0["Length"], 1e-9)
    trunk_len = max((lv0["Length"] + rng.uniform(-1, 1) * lv0["LengthV"]) * scale, 1e-3)
    r_trunk = trunk_len * params["Ratio"] * params["0Scale"]
    levels = [_trunk(params, trunk_len, r_trunk, rng)]
    for n in range(1, params["Levels"]):
        nxt = _grow_level(levels[-1], n, params, trunk_len, scale, rng)
        if not len(nxt.rows.j0):
            break
        levels.append(nxt)
    leaves = _leaves(levels[-1], params, rng)
    levels[0] = _Level(_refine(levels[0].rows, TRUNK_POINTS), 0, levels[0].base,
                       levels[0].offset_in_parent, levels[0].parent_length)
    sk = _assemble(levels, params)
    # the top at the height asked; the trunk's base radius from the height-diameter law
    top = float(np.nanmax(sk.points[:, 2]))
    f = (height / top) if height is not None else 1.0
    h = top * f
    b = params.model["height_diameter_exponent"]
    s0 = params["Scale"]
    r_target = (s0 * params["Ratio"] * (params["0Scale"] + rng.uniform(-1, 1)
                * params["0ScaleV"]) * (h / s0) ** (1.0 / b))
    sk.points *= f
    sk.arc *= f
    sk.attach *= f
    sk.stem_length *= f
    trunk_base = sk.radius[sk.ptr[np.flatnonzero(sk.level == 0)]].max()
    sk.radius *= r_target / max(trunk_base, 1e-12)
    leaves.position = leaves.position * f
    return Tree(params, sk, leaves, h)
