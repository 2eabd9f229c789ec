"""Crowns grown by competition for the space between them: each crown's reach by azimuth.

In a closed stand a crown is not a disc about its stem. Its branches stop where they meet a
neighbour's (shade and abrasion) and the tree's growth goes to the side that is free: crowns
are asymmetric and fill the gaps between them (crown plasticity; Seidel, Leuschner, Müller
and Krause 2011, *Forest Ecology and Management* 261(11), 2123-2132; Purves, Lichstein and
Pacala 2007, *PLoS ONE* 2(9), e870). :func:`crown_reach` gives every crown's reach per
azimuth sector from its stand:

1. The crown as the inventory measures it: radius ``R`` and, when known, the displacement
   of its centre from the stem, drawn as ``R (1 + a cos t)`` at azimuth ``t`` from that
   displacement (``a = |offset| / R``, at most :data:`MAX_ASYMMETRY`; the law of
   :func:`procgen.trees.place_tree`).
2. Pushed back where a neighbour's crown is: where two such crowns overlap, each keeps the
   part on its side of the line that splits the stems' distance in proportion to their
   radii (``D R_i / (R_i + R_j)`` from stem ``i``), so the overlap is shared and no space
   is held twice.
3. Extended into open space: the sectors that meet no neighbour reach further, by one
   factor of the crown's shape, until the crown has the area it had (the inventory's crown
   size is kept; competition moves it, it does not make it), never past the splitting
   line of a neighbour, into a neighbour's crown, or beyond ``reach_max`` radii.

A lone crown keeps its shape; two crowns closer than the sum of their radii are shorter
towards each other than away from each other. No randomness: the same stand gives the
same reaches.

>>> import numpy as np
>>> r = crown_reach(np.array([[0.0, 0.0], [5.0, 0.0], [40.0, 0.0]]), np.array([3.0, 3.0, 3.0]))
>>> r.shape, bool(np.all(r[2] == 3.0))   # (trees, sectors); the lone tree stays round
((3, 36), True)
>>> float(r[0, 0]), float(r[0, 18]) > 3.0   # towards its neighbour: half-way; away: further
(2.5, True)
"""

from __future__ import annotations

import numpy as np

from core.validate import check_array

__all__ = ["crown_reach", "offset_reach", "MAX_ASYMMETRY", "REACH_MAX", "SECTORS"]

MAX_ASYMMETRY = 0.6
"""Largest ``a = |offset| / R`` of a displaced crown ``R (1 + a cos t)``: its reach on its
open side is at most 1.6 radii, on the other at least 0.4."""

REACH_MAX = 1.6
"""Default bound on a crown's reach into open space, in crown radii: as far as the most
displaced crown of :data:`MAX_ASYMMETRY` reaches. (lidR's segmented crowns of the
MixedConifer tile reach 1.36 radii from their tops in median, 1.83 at the 90th
percentile: crowns do reach that far on their free side.)"""

SECTORS = 36
"""Azimuth sectors of a crown's reach (10 degrees each)."""

_STEP = 0.05  # metres between the samples along each sector's ray


def offset_reach(radius: float, offset, sectors: int = SECTORS) -> np.ndarray:
    """Reach ``(sectors,)`` of a crown of ``radius`` displaced by ``offset (2,)`` from its
    stem: ``R (1 + a cos(t - phi))``, ``a = min(|offset| / R, MAX_ASYMMETRY)``, sector ``k``
    at azimuth ``2 pi k / sectors`` from +x.

    >>> offset_reach(2.0, (0.0, 0.0), 4).tolist()
    [2.0, 2.0, 2.0, 2.0]
    >>> np.round(offset_reach(2.0, (0.5, 0.0), 4), 6).tolist()
    [2.5, 2.0, 1.5, 2.0]
    """
    d = np.asarray(offset, np.float64).reshape(2)
    t = 2 * np.pi * np.arange(sectors) / sectors
    m = float(np.hypot(*d))
    if not m > 0:
        return np.full(sectors, float(radius))
    a = min(m / max(float(radius), 1e-9), MAX_ASYMMETRY)
    return radius * (1.0 + a * np.cos(t - np.arctan2(d[1], d[0])))


def crown_reach(xy: np.ndarray, radii: np.ndarray, *, offsets: np.ndarray | None = None,
                sectors: int = SECTORS, reach_max: float = REACH_MAX) -> np.ndarray:
    """Each crown's reach per azimuth sector after competing with its neighbours.

    Parameters
    ----------
    xy : (n, 2) float64
        Stem positions, metres.
    radii : (n,) float64
        Crown radii (an inventory's: half the crown width), metres, > 0.
    offsets : (n, 2) float64, optional
        Each crown's centre from its stem (NaN or 0: none).
    sectors : int
        Azimuth sectors; sector ``k`` is centred at ``2 pi k / sectors`` from +x.
    reach_max : float
        A crown reaches into open space at most this many radii from its stem (>= 1).

    Returns
    -------
    reach : (n, sectors) float64
        Metres from the stem to the crown's edge in each sector (steps of 5 cm where a
        neighbour sets it).
    """
    xy = check_array(xy, "xy", shape=(None, 2))
    n = len(xy)
    radii = check_array(radii, "radii", shape=(n,))
    if np.any(~(radii > 0)):
        raise ValueError(f"radii: expected every crown radius > 0, got min {radii.min()!r}")
    if not reach_max >= 1:
        raise ValueError(f"reach_max: expected >= 1 (crown radii), got {reach_max!r}")
    sectors = int(sectors)
    if sectors < 4:
        raise ValueError(f"sectors: expected at least 4, got {sectors}")
    off = (np.zeros((n, 2)) if offsets is None
           else np.nan_to_num(check_array(offsets, "offsets", shape=(n, 2), finite=False)))
    base = np.stack([offset_reach(radii[i], off[i], sectors) for i in range(n)]) \
        if n else np.empty((0, sectors))
    out = base.copy()
    t = 2 * np.pi * np.arange(sectors) / sectors
    u = np.column_stack([np.cos(t), np.sin(t)])                      # (s, 2)
    span = np.maximum(base.max(axis=1), reach_max * radii)           # farthest any can reach
    for i in range(n):
        d = xy - xy[i]
        dist = np.hypot(d[:, 0], d[:, 1])
        near = np.flatnonzero((dist < span[i] + base.max(axis=1)) & (np.arange(n) != i))
        if len(near) == 0:
            continue
        if np.any(dist[near] == 0):
            raise ValueError(f"xy: two stems at the same place ({xy[i].tolist()})")
        rho = np.arange(_STEP / 2, span[i] + _STEP, _STEP)            # (m,) along each ray
        p = u[:, None, :] * rho[None, :, None]                        # (s, m, 2) from stem i
        claimed = np.zeros(p.shape[:2], bool)   # in a neighbour's crown, on its side
        taken = np.zeros(p.shape[:2], bool)     # in a neighbour's crown or its cell
        for j in near:
            q = p - d[j]                                              # from stem j
            ang = np.mod(np.arctan2(q[..., 1], q[..., 0]), 2 * np.pi) * sectors / (2 * np.pi)
            k0 = np.floor(ang).astype(np.int64) % sectors
            w = ang - np.floor(ang)
            rj = (1 - w) * base[j, k0] + w * base[j, (k0 + 1) % sectors]
            inside_j = np.hypot(q[..., 0], q[..., 1]) <= rj
            nij = d[j] / dist[j]
            beyond = p @ nij > dist[j] * radii[i] / (radii[i] + radii[j])
            claimed |= inside_j & beyond
            taken |= inside_j | beyond
        own = rho[None, :] <= base[i][:, None]
        # the crown as measured, up to the first sample a neighbour holds
        keep = _run_length(own & ~claimed) * _STEP
        pushed = np.minimum(base[i], keep)
        room = np.minimum(_run_length(~taken) * _STEP, span[i])
        area0 = np.sum(base[i] ** 2)
        grow = np.linspace(1.0, reach_max, 121)
        cand = np.maximum(pushed, np.minimum(grow[:, None] * base[i], room))   # (g, s)
        cap = np.maximum(reach_max * radii[i], base[i])
        cand = np.minimum(cand, np.maximum(cap, pushed))
        ok = np.flatnonzero(np.sum(cand ** 2, axis=1) >= area0 - 1e-9)
        out[i] = cand[ok[0]] if len(ok) else cand[-1]
    return out


def _run_length(free: np.ndarray) -> np.ndarray:
    """Per row of ``free (s, m)``: how many samples from the start are all True."""
    blocked = ~free
    first = np.argmax(blocked, axis=1)
    return np.where(blocked.any(axis=1), first, free.shape[1]).astype(np.float64)
