"""Crown allometries of the central European mountain species: how long and how wide a
tree's crown is, from its size, its neighbours and its site.

Two published models of the Austrian growth simulator PROGNAUS, fitted on the Austrian
National Forest Inventory, per species (ANFI codes: 1 Norway spruce, 2 silver fir, 3 larch,
4 Scots pine, 10 beech, 14 maple, 28 other broadleaves):

- **Crown ratio** (crown length / height), Hasenauer & Monserud (1996), *A crown ratio model
  for Austrian forests*, Forest Ecology and Management 84: 49-60, with the coefficients of
  Hasenauer (2000), *Die simultanen Eigenschaften von Waldwachstumsmodellen*, Paul Parey::

      CR = 1 / (1 + exp(a0 + b1 100 h/d + b2 h + b3 d^2 + c1 BAL + c2 ln CCF
                        + d1 E/100 + d2 (E/100)^2 + d3 S + d4 S^2
                        + d5 S sin(asp) + d6 S cos(asp)))

  ``h`` height (m), ``d`` dbh (cm), ``BAL`` the basal area of larger trees (m²/ha, Wykoff
  1990), ``CCF`` the crown competition factor (Krajicek et al. 1961), ``E`` elevation (m),
  ``S`` slope (fraction: 0.5 = 50 %), ``asp`` aspect. Crowns are longer with less
  competition and on shade-tolerant species: at the same size and competition spruce and
  fir carry their crowns lower than larch and pine (the doctest below).
- **Open-grown crown diameter**, Hasenauer (1997), *Dimensional relationships of open-grown
  trees in Austria*, Forest Ecology and Management 96: 197-206: ``cd = exp(b0 + b1 ln d)``
  (m, d in cm). Its crowns give the stand's ``CCF`` (the sum of the open-grown crown areas
  over the stand's area, in %); in a closed stand (``CCF > 100``: open-grown crowns would
  more than cover the ground) each crown's area is scaled by ``100 / CCF``, so the crowns
  together cover the ground once, as a closed canopy does (our rule on Krajicek's
  definition: ``CCF = 100`` is the density at which open-grown crowns just close).

The coefficients are those of PROGNAUS as published (Vospernik's R package
``PrognausBaseSV``, files ``CR.R`` and ``Comp.R``); the sycamore maple has its own
open-grown crown, and the crown ratio of "other broadleaves".

>>> import numpy as np
>>> codes = ["PIAB", "ABAL", "LADE", "PISY", "FASY"]
>>> cr = crown_ratio(codes, dbh_cm=np.full(5, 30.0), height_m=np.full(5, 25.0),
...                  bal=np.full(5, 20.0), ccf=250.0, elevation_m=1000.0, slope=0.5,
...                  aspect_deg=180.0)
>>> dict(zip(codes, np.round(cr, 2).tolist()))
{'PIAB': 0.61, 'ABAL': 0.51, 'LADE': 0.43, 'PISY': 0.38, 'FASY': 0.6}
>>> round(float(open_crown_diameter(["PIAB"], np.array([30.0]))[0]), 2)
6.47
"""

from __future__ import annotations

import numpy as np

__all__ = ["HAS_ALLOMETRY", "crown_ratio", "open_crown_diameter", "basal_area_larger",
           "stand_crowns", "HD_RATIO", "crown_displacement", "CROWN_REACH"]

# a0, b1, b2, b3, c1, c2, d1, d2, d3, d4, d5, d6 (Hasenauer 2000; b3 as published / 10^4)
_CROWN_RATIO = {
    1: (-3.893748, 0.011232, 0.02687, -0.6358e-4, 0.010574, 0.404436, -0.043123, 0.0, 0.0,
        -0.222507, -0.040207, 0.147378),
    2: (-2.364763, 0.007637, 0.022854, -0.74049e-4, 0.010184, 0.270049, -0.030867, 0.0, 0.0,
        -0.555051, -0.030725, 0.158594),
    3: (-2.859456, 0.009106, 0.027547, 0.0, 0.009133, 0.373768, -0.037037, 0.0, -0.251112,
        0.0, 0.060256, 0.106756),
    4: (-1.676984, 0.002942, 0.026387, 0.0, 0.013054, 0.245749, 0.0, -0.001494, 0.0,
        -0.413472, 0.079776, 0.167692),
    10: (-3.853739, 0.007435, 0.024684, -1.35686e-4, 0.0, 0.384344, 0.015155, 0.0, 0.144669,
         0.0, 0.0, 0.0),
    28: (-1.995385, 0.00649, 0.019637, -1.2235e-4, 0.003633, 0.158546, 0.0, 0.0, 0.0,
         0.17509, 0.015639, 0.074927),
}
# b0, b1 of ln(cd) = b0 + b1 ln(d) (Hasenauer 1997)
_OPEN_CROWN = {1: (-0.3232, 0.6441), 2: (0.092, 0.538), 3: (-0.3396, 0.6823),
               4: (-0.1797, 0.6267), 10: (0.2662, 0.6072), 14: (0.418, 0.5285)}
# species code -> (crown ratio model, open-grown crown model)
_ANFI = {"PIAB": (1, 1), "ABAL": (2, 2), "LADE": (3, 3), "PISY": (4, 4), "FASY": (10, 10),
         "ACPS": (28, 14)}

HAS_ALLOMETRY = frozenset(_ANFI)
"""The species codes these models cover."""

HD_RATIO = 80.0
"""Height (m) over dbh (m) of a stand-grown tree whose dbh is not given (an assumption of
ours: the usual h/d of dominant and co-dominant trees in closed central European stands)."""

# the model's range of elevations (its data: 200-2200 m)
_ELEVATION = (200.0, 2200.0)


def _codes(codes) -> list[str]:
    out = [str(c).upper() for c in np.atleast_1d(codes)]
    bad = sorted({c for c in out if c not in _ANFI})
    if bad:
        raise ValueError(f"codes: expected species with crown allometries "
                         f"({', '.join(sorted(_ANFI))}), got {', '.join(bad)}")
    return out


def crown_ratio(codes, *, dbh_cm, height_m, bal, ccf, elevation_m=600.0, slope=0.0,
                aspect_deg=180.0) -> np.ndarray:
    """Crown length / height (Hasenauer & Monserud 1996), per tree.

    Parameters
    ----------
    codes : (n,) str
        Species codes of :data:`HAS_ALLOMETRY`.
    dbh_cm, height_m, bal : (n,) float
        Stem diameter at 1.3 m (cm), height (m), basal area of the larger trees (m²/ha).
    ccf : float or (n,) float
        Crown competition factor of the stand (%); below 1 taken as 1.
    elevation_m : float or (n,)
        Clamped to the model's 200-2200 m.
    slope : float or (n,)
        Ground slope as a fraction (rise / run).
    aspect_deg : float or (n,)
        Direction the slope faces, degrees clockwise from north.

    Returns
    -------
    (n,) float64 in (0, 1)
    """
    c = np.array([_CROWN_RATIO[_ANFI[k][0]] for k in _codes(codes)]).reshape(-1, 12).T
    d = np.asarray(dbh_cm, np.float64)
    h = np.asarray(height_m, np.float64)
    e = np.clip(np.asarray(elevation_m, np.float64), *_ELEVATION) / 100.0
    s = np.asarray(slope, np.float64)
    asp = np.radians(np.asarray(aspect_deg, np.float64))
    lccf = np.log(np.maximum(np.asarray(ccf, np.float64), 1.0))
    x = (c[0] + c[1] * 100.0 * h / d + c[2] * h + c[3] * d * d + c[4] * np.asarray(bal)
         + c[5] * lccf + c[6] * e + c[7] * e * e + c[8] * s + c[9] * s * s
         + c[10] * s * np.sin(asp) + c[11] * s * np.cos(asp))
    return 1.0 / (1.0 + np.exp(x))


def open_crown_diameter(codes, dbh_cm) -> np.ndarray:
    """Crown diameter (m) of an open-grown tree of ``dbh_cm`` (Hasenauer 1997), per tree."""
    c = np.array([_OPEN_CROWN[_ANFI[k][1]] for k in _codes(codes)]).reshape(-1, 2).T
    return np.exp(c[0] + c[1] * np.log(np.asarray(dbh_cm, np.float64)))


def basal_area_larger(dbh_cm: np.ndarray, area_ha: float) -> np.ndarray:
    """Each tree's BAL: the basal area (m²/ha) of the trees of larger dbh on ``area_ha``.

    >>> basal_area_larger(np.array([20.0, 40.0, 30.0]), 1.0).round(4).tolist()
    [0.1963, 0.0, 0.1257]
    """
    d = np.asarray(dbh_cm, np.float64)
    ba = np.pi * (d / 200.0) ** 2 / float(area_ha)
    order = np.argsort(-d, kind="stable")
    larger = np.empty_like(ba)
    larger[order] = np.concatenate([[0.0], np.cumsum(ba[order])[:-1]])
    # trees of equal dbh do not count each other
    for v in np.unique(d):
        same = d == v
        if same.sum() > 1:
            larger[same] = larger[same].min()
    return larger


def stand_crowns(codes, *, height_m, dbh_cm, area_ha: float, elevation_m=600.0, slope=0.0,
                 aspect_deg=180.0) -> dict:
    """Crown ratio and crown radius of every tree of a stand whose species
    :data:`HAS_ALLOMETRY` covers (NaN for the others, which count in the competition with
    their basal area only).

    Parameters
    ----------
    codes : (n,) str
    height_m, dbh_cm : (n,) float
        A dbh that is NaN or not positive is ``100 height / HD_RATIO``.
    area_ha : float
        The stand's area (for BAL and CCF).
    elevation_m, slope, aspect_deg : float or (n,)
        See :func:`crown_ratio`.

    Returns
    -------
    dict
        ``crown_ratio``, ``crown_radius`` (m), ``dbh_cm`` (n,), ``ccf`` (%).
    """
    codes = np.array([str(c).upper() for c in np.atleast_1d(codes)])
    h = np.asarray(height_m, np.float64)
    d = np.asarray(dbh_cm, np.float64) if dbh_cm is not None else np.full(len(h), np.nan)
    d = np.where(np.isfinite(d) & (d > 0), d, 100.0 * h / HD_RATIO)
    known = np.isin(codes, sorted(_ANFI))
    n = len(h)
    ratio, radius = np.full(n, np.nan), np.full(n, np.nan)
    ccf = 0.0
    if np.any(known):
        cd = open_crown_diameter(codes[known], d[known])
        ccf = float(np.sum(np.pi * cd ** 2 / 4) / (area_ha * 1e4) * 100.0)
        bal = basal_area_larger(d, area_ha)[known]

        def pick(v):
            v = np.asarray(v, np.float64)
            return v[known] if v.ndim else v

        ratio[known] = crown_ratio(codes[known], dbh_cm=d[known], height_m=h[known], bal=bal,
                                   ccf=ccf, elevation_m=pick(elevation_m), slope=pick(slope),
                                   aspect_deg=pick(aspect_deg))
        radius[known] = cd / 2 * np.sqrt(min(1.0, 100.0 / max(ccf, 1e-9)))
    return {"crown_ratio": ratio, "crown_radius": radius, "dbh_cm": d, "ccf": ccf}


CROWN_REACH = 1.5
"""How far from its stem a crown may take its growing space, in crown radii (its
displacement stays under half a radius)."""


def crown_displacement(xy: np.ndarray, radius: np.ndarray, *, reach: float = CROWN_REACH,
                       samples: int = 15) -> np.ndarray:
    """Where each crown's centre moves from its stem in a closed stand: to the centroid of
    its growing space.

    Crowns are plastic: they grow away from their neighbours into the open space around
    them, so a crown's centre is displaced from its stem towards gaps (Rouvinen and
    Kuuluvainen 1997, Can. J. For. Res. 27: 890-902, doi:10.1139/x97-012; in European beech
    Schröter et al. 2012, Eur. J. For. Res. 131: 787-798, doi:10.1007/s10342-011-0552-y).
    The growing space of a tree is its cell of the power diagram of the stems weighted by
    their crown radii (the points nearer to it than to any other crown, the distance to a
    crown ``d^2 - r^2``: the area potentially available to a tree of Brown 1965, weighted
    by size) within ``reach`` crown radii of its stem; the displacement is the centroid of
    that area, estimated on ``samples x samples`` points over the square about the stem.
    Crowns that the allometries size to cover the ground once (:func:`stand_crowns`) but
    centred on stems standing at random overlap where stems crowd and leave the ground
    open where they are sparse; moved so, they overlap less and leave less open.

    Parameters
    ----------
    xy : (n, 2) float
        Stems, metres.
    radius : (n,) float
        Crown radii, metres (> 0).

    Returns
    -------
    (n, 2) float64
        Each crown's displacement from its stem (zero for a tree with no neighbour within
        reach, and by symmetry for one amid a regular lattice).

    >>> d = crown_displacement(np.array([[0.0, 0.0], [3.0, 0.0]]), np.array([2.0, 2.0]))
    >>> bool(d[0, 0] < 0 < d[1, 0]), np.allclose(d[0], -d[1]), np.allclose(d[:, 1], 0)
    (True, True, True)
    """
    from scipy.spatial import cKDTree

    p = np.asarray(xy, np.float64).reshape(-1, 2)
    r = np.asarray(radius, np.float64).reshape(-1)
    if len(r) != len(p):
        raise ValueError(f"radius: expected {len(p)} values (one per stem), got {len(r)}")
    if not np.all(r > 0):
        raise ValueError("radius: expected every crown radius > 0")
    if not reach > 0:
        raise ValueError(f"reach: expected > 0, got {reach}")
    out = np.zeros_like(p)
    if len(p) < 2:
        return out
    u = (np.arange(samples) + 0.5) / samples * 2.0 - 1.0
    grid = np.stack(np.meshgrid(u, u), -1).reshape(-1, 2)
    grid = grid[np.sum(grid ** 2, 1) <= 1.0]            # the disc of radius 1
    tree = cKDTree(p)
    rmax = float(r.max())
    for i in range(len(p)):
        q = p[i] + reach * r[i] * grid
        nb = np.array(tree.query_ball_point(p[i], reach * r[i] + rmax), np.int64)
        nb = nb[nb != i]
        if not len(nb):
            continue
        own = np.sum((q - p[i]) ** 2, 1) - r[i] ** 2
        other = (np.sum((q[:, None, :] - p[None, nb]) ** 2, -1) - r[nb][None] ** 2).min(1)
        mine = own <= other
        if np.any(mine):
            out[i] = q[mine].mean(axis=0) - p[i]
    return out
