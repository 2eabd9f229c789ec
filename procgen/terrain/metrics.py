"""Geomorphometry: the figures that tell a landscape carved by water from noise.

All are measured after D8 routing of the surface as it is (no filling):

- :func:`pit_share`: interior cells with no strictly lower neighbour (closed pits and
  flats), 0-0.1 % on real DEMs, several % on fractal noise;
- :func:`concavity`: theta of Flint's law ``S ~ A^-theta`` on the channels (real
  mountains 0.2-0.6, median 0.43; Gailleton et al. 2021);
- :func:`bifurcation_ratio`: Horton's ``R_b = N_w / N_{w+1}`` of Strahler-ordered streams
  (3-5 in real networks);
- :func:`hack_exponent`: ``h`` of Hack's law ``L ~ A^h``, ``L`` the longest flow path
  above a channel cell (0.5-0.6);
- :func:`hypsometric_integral`: ``(mean - min) / (max - min)`` (0.3-0.65).

>>> import numpy as np
>>> xx, yy = np.meshgrid(np.linspace(-1, 1, 65), np.linspace(-1, 1, 65))
>>> round(hypsometric_integral(xx), 3)                      # a plane
0.5
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from core.validate import check_array, check_int, check_positive
from procgen.terrain.flow import FlowRouting, boundary_mask, fill_depressions, route_flow

__all__ = ["pit_share", "reach_slope", "concavity", "strahler_order", "bifurcation_ratio",
           "hack_exponent", "hypsometric_integral", "TerrainFigures", "terrain_figures"]


def pit_share(z) -> float:
    """Share of the interior cells (finite, not on the boundary) that have no strictly
    lower D8 neighbour: water that reaches them stays."""
    z = check_array(z, "heights", shape=(None, None), finite=False)
    r, c = z.shape
    interior = np.isfinite(z) & ~boundary_mask(z)
    if not interior.any():
        return 0.0
    pad = np.pad(z, 1, constant_values=np.nan)
    lower = np.zeros(z.shape, bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                lower |= pad[1 + di:1 + di + r, 1 + dj:1 + dj + c] < z
    return float((interior & ~lower).sum() / interior.sum())


def _channels(flow: FlowRouting, min_area: float | None) -> np.ndarray:
    a = flow.area.ravel()
    cell = float(np.min(a[a > 0])) if (a > 0).any() else 1.0
    thr = 100.0 * cell if min_area is None else min_area
    return (a >= thr) & (flow.distance > 0)


def reach_slope(z, flow: FlowRouting, reach: int = 1) -> np.ndarray:
    """Slope from each cell to the cell ``reach`` receivers down its flow path (fewer at a
    base level), ``(rows, cols)``; 0 at base levels. Over several cells it sees through
    the steps of a DEM stored in whole metres."""
    zf = np.asarray(z, np.float64).ravel()
    idx = np.arange(len(zf))
    length = np.zeros(len(zf))
    for _ in range(int(reach)):
        length += flow.distance[idx]
        idx = flow.receivers[idx]
    out = np.zeros(len(zf))
    m = length > 0
    out[m] = (zf[m] - zf[idx[m]]) / length[m]
    return out.reshape(flow.shape)


def concavity(z, *, spacing=1.0, min_area: float | None = None,
              flow: FlowRouting | None = None, reach: int = 1) -> float:
    """theta of ``S = k_s A^-theta``: minus the slope of ``log S`` on ``log A``, fitted on
    channel cells (drainage area >= ``min_area``, default 100 cells) with a positive
    slope over ``reach`` cells down the flow (:func:`reach_slope`), over logarithmic area
    bins (each bin's median slope, so the many small channels do not outweigh the few
    large ones). ``flow`` routes the water when given (a conditioned DEM's routing), the
    slopes are always those of ``z``."""
    z = check_array(z, "heights", shape=(None, None), finite=False)
    fl = flow or route_flow(z, spacing=spacing)
    s = reach_slope(z, fl, check_int(reach, "reach", 1)).ravel()
    ch = _channels(fl, min_area) & (s > 0)
    if ch.sum() < 3:
        raise ValueError("heights: fewer than 3 channel cells with a positive slope")
    la, ls = np.log10(fl.area.ravel()[ch]), np.log10(s[ch])
    edges = np.linspace(la.min(), la.max() + 1e-9, 21)
    idx = np.digitize(la, edges) - 1
    xs, ys = [], []
    for b in range(len(edges) - 1):
        sel = idx == b
        if sel.sum() >= 3:
            xs.append(np.median(la[sel]))
            ys.append(np.median(ls[sel]))
    if len(xs) < 2:
        xs, ys = la, ls
    return float(-np.polyfit(xs, ys, 1)[0])


@nb.njit(cache=True)
def _strahler(rec, stack, channel):
    n = len(rec)
    order = np.zeros(n, np.int64)
    top = np.zeros(n, np.int64)     # the highest order among a cell's channel donors
    count = np.zeros(n, np.int64)   # how many donors carry that order
    for q in range(n - 1, -1, -1):
        k = stack[q]
        if not channel[k]:
            continue
        if top[k] == 0:
            order[k] = 1
        elif count[k] >= 2:
            order[k] = top[k] + 1
        else:
            order[k] = top[k]
        r = rec[k]
        if r != k and channel[r]:
            if order[k] > top[r]:
                top[r] = order[k]
                count[r] = 1
            elif order[k] == top[r]:
                count[r] += 1
    return order


def strahler_order(receivers, stack, channel) -> np.ndarray:
    """Strahler order of each channel cell (0 elsewhere): 1 at channel heads; where two
    streams of the highest order among a cell's donors meet, one more."""
    rec = np.asarray(receivers, np.int64)
    return _strahler(rec, np.asarray(stack, np.int64), np.asarray(channel, bool))


def bifurcation_ratio(receivers, stack, channel) -> float:
    """Horton's bifurcation ratio: ``10^-slope`` of ``log10 N_w`` on the Strahler order
    ``w``, ``N_w`` the number of streams (maximal runs of one order) of order ``w``;
    the highest order (often one stream cut by the grid edge) is left out when there are
    three or more."""
    rec = np.asarray(receivers, np.int64)
    order = strahler_order(rec, stack, channel)
    ch = order > 0
    # a stream starts at a channel cell whose donors carry a lower order (or none)
    same_donor = np.zeros(len(rec), bool)
    k = np.nonzero(ch & (rec != np.arange(len(rec))))[0]
    same = order[rec[k]] == order[k]
    same_donor[rec[k][same]] = True
    starts = ch & ~same_donor
    w_max = int(order.max())
    if w_max < 2:
        raise ValueError("channel: expected a network of Strahler order 2 or more")
    ws = np.arange(1, w_max + 1)
    counts = np.array([(starts & (order == w)).sum() for w in ws], float)
    if w_max >= 3:
        ws, counts = ws[:-1], counts[:-1]
    return float(10 ** -np.polyfit(ws, np.log10(counts), 1)[0])


@nb.njit(cache=True)
def _longest_path(rec, stack, dist):
    n = len(rec)
    out = np.zeros(n)
    for q in range(n - 1, -1, -1):
        k = stack[q]
        r = rec[k]
        if r != k:
            cand = out[k] + dist[k]
            if cand > out[r]:
                out[r] = cand
    return out


def hack_exponent(z, *, spacing=1.0, min_area: float | None = None,
                  flow: FlowRouting | None = None) -> float:
    """``h`` of Hack's law ``L = c A^h``: the slope of ``log L`` on ``log A`` over the
    channel cells, ``L`` the longest flow path from a divide to the cell."""
    z = check_array(z, "heights", shape=(None, None), finite=False)
    fl = flow or route_flow(z, spacing=spacing)
    length = _longest_path(fl.receivers, fl.stack, fl.distance)
    ch = _channels(fl, min_area) & (length > 0)
    if ch.sum() < 3:
        raise ValueError("heights: fewer than 3 channel cells")
    return float(np.polyfit(np.log10(fl.area.ravel()[ch]), np.log10(length[ch]), 1)[0])


def hypsometric_integral(z) -> float:
    """``(mean - min) / (max - min)`` of the finite heights (Strahler 1952)."""
    z = check_array(z, "heights", shape=(None, None), finite=False)
    v = z[np.isfinite(z)]
    span = float(v.max() - v.min()) if v.size else 0.0
    if span <= 0:
        raise ValueError("heights: expected a relief > 0")
    return float((v.mean() - v.min()) / span)


@dataclass
class TerrainFigures:
    """The five figures of one heightfield (see the module docstring)."""

    pit_share: float
    concavity: float
    bifurcation_ratio: float
    hack_exponent: float
    hypsometric_integral: float

    def to_dict(self) -> dict:
        return {k: float(v) for k, v in self.__dict__.items()}


def terrain_figures(z, *, spacing=1.0, min_area: float | None = None,
                    fill: bool = False, reach: int = 1) -> TerrainFigures:
    """All five figures, on one D8 routing of ``z``; channels are the cells draining
    ``min_area`` square metres or more (default: 100 cells).

    The pit share is always that of ``z`` as it is. With ``fill`` the network figures
    are measured on ``z`` with its depressions and flats drained (Priority-Flood+epsilon),
    as a geomorphometry tool conditions a raw DEM (integer metres make flats everywhere);
    without, on ``z`` as it is. The concavity's slopes are those of ``z`` as it is, over
    ``reach`` cells.
    """
    z = check_array(z, "heights", shape=(None, None), finite=False)
    if min_area is not None:
        check_positive(min_area, "min_area")
    pits = pit_share(z)
    hyps = hypsometric_integral(z)
    routed = fill_depressions(z, epsilon=1e-9) if fill else z
    fl = route_flow(routed, spacing=spacing)
    ch = _channels(fl, min_area)
    return TerrainFigures(pits, concavity(z, flow=fl, min_area=min_area, reach=reach),
                          bifurcation_ratio(fl.receivers, fl.stack, ch),
                          hack_exponent(z, flow=fl, min_area=min_area), hyps)
