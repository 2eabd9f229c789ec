"""Terrain shaped by water and gravity: stream-power landscape evolution, hydraulic and
thermal erosion of any heightfield.

**Stream power** (Braun & Willett 2013, the FastScape solver): the land rises at
``uplift`` and rivers cut it at ``K A^m S^n`` (``A`` drainage area, ``S`` slope to the
D8 receiver), with linear hillslope diffusion ``D lap(z)`` between. Each step routes the
flow on the surface with its depressions filled (sediment fills a lake before the river
cuts its outlet; once the land drains, only the few pits diffusion leaves are filled,
each from its pit outward), orders the cells by the stack, and solves the erosion implicitly from
the outlets up, which is stable at any step and O(n). At steady state
``S = (U / K)^(1/n) A^(-m/n)``: the channel concavity is ``m / n``.

**Hydraulic** (the dissolve-and-deposit rule of Musgrave, Kolb & Mace 1989, carried
along the flow network): each step the rain is routed downhill on the surface with its
lakes filled to their spill points (priority-flood), and the water walks the network
from the divides down, dissolving the bed where it can carry more than it does
(capacity ``k q^m S``: discharge and slope; channels only, from a critical drainage area
on) and dropping its load where it slows or stands in a lake; hillslope creep between
steps. It runs in cell units (heights over
the grid step) so a rate means the same on a 10 m and a 10 km terrain.

**Thermal** (Musgrave, Kolb & Mace 1989): material above the talus angle slides to
lower neighbours until slopes rest at it.

>>> import numpy as np
>>> from procgen.terrain.heightfield import fractal_terrain
>>> z = fractal_terrain(33, rng=np.random.default_rng(0), height=20.0)
>>> out = erode(z, spacing=30.0, kind="thermal", config=ErosionConfig(talus_deg=30.0))
>>> bool(np.abs(np.diff(out, axis=1)).max() <= np.abs(np.diff(z, axis=1)).max())
True
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numba as nb
import numpy as np

from core.config import Config, option
from core.validate import check_array, check_choice
from procgen.terrain.flow import (
    _accumulate,
    _receivers,
    _spacing,
    _stack,
    boundary_mask,
    drain,
)

__all__ = ["ErosionConfig", "erode", "stream_power", "hydraulic_erosion", "thermal_erosion",
           "chi", "KINDS"]

log = logging.getLogger(__name__)

#: hydraulic erosion's steps when ``iterations`` is not given
HYDRAULIC_STEPS = 100
#: thermal erosion's steps when ``iterations`` is not given
THERMAL_STEPS = 400

#: the erosion models, ``none`` included
KINDS = ("none", "hydraulic", "thermal", "stream-power")


@dataclass(frozen=True)
class ErosionConfig(Config):
    """Rates of the erosion models (each model reads its own)."""

    years: float = option(1e4, unit="yr", range="(0, 1e9]",
                          help="stream power: model time")
    dt_years: float = option(250.0, unit="yr", range="(0, 1e9]",
                             help="stream power: time step (the solver is implicit)")
    erodibility: float = option(1e-3, unit="m^(1-2m)/yr", range="[0, inf)",
                                help="stream power: K of the incision rate K A^m S^n")
    area_exponent: float = option(0.5, range="(0, 2)",
                                  help="stream power and hydraulic: m of A^m (q^m)")
    slope_exponent: float = option(1.0, range="(0, 4)", help="stream power: n")
    uplift: float | None = option(None, unit="m/yr", range="[0, inf)",
                                  help="stream power: rock uplift rate; default: the rate "
                                       "whose steady state keeps the input's relief")
    diffusivity: float | None = option(None, unit="m2/yr", range="[0, inf)",
                                       help="stream power: hillslope diffusivity; default "
                                            "1e-3 grid steps squared per year")
    iterations: int | None = option(None, range="[1, 100000]",
                                    help="hydraulic and thermal: simulation steps; default "
                                         "100 for hydraulic (each routes the water over "
                                         "the whole terrain), 400 for thermal")
    rain: float = option(0.01, range="[0, inf)",
                         help="hydraulic: water falling on each cell a step, in grid steps "
                              "of depth")
    capacity: float = option(1.0, range="[0, inf)",
                             help="hydraulic: k of the sediment the water can carry, "
                                  "k q^m S (q discharge, S slope)")
    dissolving: float = option(0.3, range="[0, 1]",
                               help="hydraulic: share of the missing capacity picked up a step")
    deposition: float = option(0.3, range="[0, 1]",
                               help="hydraulic: share of the excess sediment dropped a step")
    evaporation: float = option(0.0, range="[0, 1)",
                                help="hydraulic: share of the water lost at each cell it "
                                     "passes (evaporation, seepage)")
    channel_cells: float = option(40.0, range="[0, inf)",
                                  help="hydraulic: the drainage area, in cells, below which "
                                       "water runs off as sheet flow and does not "
                                       "dissolve the bed")
    creep: float = option(0.05, range="[0, 10]",
                          help="hydraulic: hillslope creep between steps (linear "
                               "diffusion), in grid steps squared")
    talus_deg: float = option(35.0, unit="deg", range="(0, 90)",
                              help="thermal: the angle of repose")
    thermal_rate: float = option(0.5, range="(0, 1]",
                                 help="thermal: share of the excess moved a step")


# ----------------------------------------------------------------------- stream power
@nb.njit(cache=True)
def _implicit_incision(h, rec, dist, stack, area, kdt, m, n):
    for q in range(len(stack)):
        k = stack[q]
        r = rec[k]
        if r == k:
            continue
        f = kdt * area[k] ** m / dist[k] ** n
        hr = h[r]
        if n == 1.0:
            h[k] = (h[k] + f * hr) / (1.0 + f)
        else:  # Newton on x - h0 + f (x - hr)^n = 0, x > hr
            h0 = h[k]
            x = h0
            for _ in range(50):
                d = max(x - hr, 1e-300)
                g = x - h0 + f * d ** n
                dg = 1.0 + n * f * d ** (n - 1.0)
                x_new = max(x - g / dg, hr + 0.5 * (x - hr))
                if abs(x_new - x) <= 1e-12 * (abs(x) + 1.0):
                    x = x_new
                    break
                x = x_new
            h[k] = x


@nb.njit(cache=True)
def _chi(rec, dist, stack, area, m):
    out = np.zeros(len(rec))
    for q in range(len(stack)):
        k = stack[q]
        r = rec[k]
        if r != k:
            out[k] = out[r] + dist[k] / max(area[k], 1e-300) ** m
    return out


def _routing(z, boundary, dx, dy, eps):
    """Receivers, distances, stack and area of ``z`` with its depressions filled."""
    filled = drain(z, boundary, eps)
    rec, dist = _receivers(filled, boundary, dx, dy)
    stack = _stack(rec)
    area = _accumulate(rec, stack, np.full(z.size, dx * dy))
    return filled, rec, dist, stack, area


def chi(z, *, spacing=1.0, area_exponent: float = 0.5) -> np.ndarray:
    """The chi coordinate (Perron & Royden 2013): ``int A^-m dx`` up each flow path from
    its outlet, on the depression-filled surface. At steady state ``z = (U / K) chi``."""
    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    _, rec, dist, stack, area = _routing(z, boundary_mask(z), dx, dy, 1e-12)
    return _chi(rec, dist, stack, area, float(area_exponent)).reshape(z.shape)


def _diffuse(z, boundary, d_dt, dx, dy):
    """Explicit linear diffusion over ``d_dt`` (m2), in stable sub-steps; boundary fixed."""
    steps = max(int(np.ceil(d_dt / (0.2 * min(dx, dy) ** 2))), 1)
    a, b = d_dt / steps / dx ** 2, d_dt / steps / dy ** 2
    inner = ~boundary
    for _ in range(steps):
        lap = np.zeros_like(z)
        lap[1:-1, 1:-1] = (a * (z[1:-1, 2:] - 2 * z[1:-1, 1:-1] + z[1:-1, :-2])
                           + b * (z[2:, 1:-1] - 2 * z[1:-1, 1:-1] + z[:-2, 1:-1]))
        z = z + np.where(inner, lap, 0.0)
    return z


def stream_power(z, *, spacing=1.0, config: ErosionConfig | None = None) -> np.ndarray:
    """Evolve ``z`` (metres) for ``config.years`` under uplift, stream-power incision and
    hillslope diffusion; the grid edge is base level (held fixed).

    Returns the new heightfield; every interior cell drains (its depressions were filled
    by sediment as they formed).
    """
    cfg = config or ErosionConfig()
    z = check_array(z, "heights", shape=(None, None)).copy()
    dx, dy = _spacing(spacing)
    boundary = boundary_mask(z)
    m, n = float(cfg.area_exponent), float(cfg.slope_exponent)
    eps = 1e-12
    uplift = cfg.uplift
    if uplift is None:
        c = chi(z, spacing=(dx, dy), area_exponent=m)
        relief = float(z.max() - z[boundary].mean())
        uplift = cfg.erodibility * (max(relief, 0.0) / max(float(c.max()), 1e-300)) ** n
    diff = 1e-3 * min(dx, dy) ** 2 if cfg.diffusivity is None else float(cfg.diffusivity)
    steps = max(int(np.ceil(cfg.years / cfg.dt_years - 1e-9)), 1)
    dt = cfg.years / steps
    lift = np.where(boundary, 0.0, uplift * dt)
    for _ in range(steps):
        z += lift
        if diff > 0:
            z = _diffuse(z, boundary, diff * dt, dx, dy)
        z, rec, dist, stack, area = _routing(z, boundary, dx, dy, eps)
        h = z.ravel().copy()
        _implicit_incision(h, rec, dist, stack, area, cfg.erodibility * dt, m, n)
        z = h.reshape(z.shape)
    log.debug("stream power: %d steps of %g yr, uplift %.3g m/yr, D %.3g m2/yr", steps, dt,
              uplift, diff)
    return z


# -------------------------------------------------------------------------- hydraulic
@nb.njit(cache=True)
def _carry(a, filled, rec, dist, stack, rain, keep, kc, ks, kd, m, qc, trap):
    """One pass of the water and its load down the routed network, upstream first: in
    a lake (``filled`` above the bed) still water drops what it carries on its way;
    elsewhere the water dissolves ``ks`` of what its capacity ``kc q^m S`` misses (never
    below the bed of the cell it flows to; only from a discharge ``qc`` on, sheet flow
    above it leaves the bed alone) or drops ``kd`` of the excess; ``keep`` of the
    water goes on at each cell (evaporation and seepage take the rest). What reaches a
    base level leaves."""
    n = len(stack)
    q = np.full(n, rain)
    load = np.zeros(n)
    af = a.ravel()
    ff = filled.ravel()
    for t in range(n - 1, -1, -1):
        k = stack[t]
        r = rec[k]
        if r == k:
            continue
        if ff[k] > af[k]:     # a lake: still water drops what it carries
            trap[k] += load[k]
            load[k] = 0.0
        else:
            drop = max(af[k] - af[r], 0.0)
            cap = kc * q[k] ** m * drop / dist[k]
            if load[k] > cap:
                d = kd * (load[k] - cap)
                af[k] += d
                load[k] -= d
            elif q[k] >= qc:
                e = min(ks * (cap - load[k]), drop)
                af[k] -= e
                load[k] += e
        load[r] += load[k]
        q[r] += q[k] * keep


def _settle(a, filled, trap) -> None:
    """The load each lake caught settles over its bed: every cell of the lake rises by
    the same share of its depth (the share the load is of the lake's volume, at most
    all of it), so the bed keeps its shape as the lake shallows and a lake with load
    enough fills to its spill point and drains."""
    from scipy import ndimage

    depth = filled - a
    lake = depth > 0
    if not lake.any():
        return
    labels, count = ndimage.label(lake, structure=np.ones((3, 3)))
    volume = np.bincount(labels.ravel(), weights=np.where(lake, depth, 0.0).ravel(),
                         minlength=count + 1)
    caught = np.bincount(labels.ravel(), weights=trap.ravel(), minlength=count + 1)
    share = np.minimum(caught / np.maximum(volume, 1e-300), 1.0)
    share[0] = 0.0
    a += share[labels] * np.where(lake, depth, 0.0)


def hydraulic_erosion(z, *, spacing=1.0, config: ErosionConfig | None = None) -> np.ndarray:
    """Hydraulic erosion of ``z`` (metres) by water that follows the land: Musgrave et
    al.'s (1989) dissolve-and-deposit rule with a capacity, carried along the flow
    network instead of between neighbours, for ``config.iterations`` steps (default
    :data:`HYDRAULIC_STEPS`), in cell units (heights over the grid step).

    Each step routes the rain on the surface with its depressions filled to their spill
    points (Priority-Flood+epsilon, Barnes et al. 2014): lakes hold still water, and
    every other cell sends its water to its D8 receiver, so the discharge ``q`` of a
    cell is the rain of everything upstream. Walking the network from the divides down,
    moving water can carry ``capacity q^m S`` (``m`` the ``area_exponent``, ``S`` the
    slope to the receiver): a cell dissolves ``dissolving`` of what is missing from its
    bed (never cutting below its receiver, so erosion makes no pit) or drops
    ``deposition`` of the excess. Water dissolves only once it drains ``channel_cells``
    cells: channels begin at a critical drainage area (Montgomery & Dietrich 1988), and
    above it sheet flow leaves the hillslopes' relief, whose converging paths make the
    network branch. Lakes trap their inflow's load, which settles over their bed
    (:func:`_settle`). Hillslope ``creep`` (linear diffusion) between steps fills the
    one-cell pits that noise leaves. What reaches the grid edge leaves.
    """
    cfg = config or ErosionConfig()
    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    step = float(np.sqrt(dx * dy))
    a = np.ascontiguousarray(z / step)
    boundary = boundary_mask(a)
    steps = HYDRAULIC_STEPS if cfg.iterations is None else int(cfg.iterations)
    for _ in range(steps):
        filled = drain(a, boundary, 1e-9)
        rec, dist = _receivers(filled, boundary, 1.0, 1.0)
        trap = np.zeros(a.size)
        _carry(a, filled, rec, dist, _stack(rec), float(cfg.rain), 1.0 - cfg.evaporation,
               float(cfg.capacity), float(cfg.dissolving), float(cfg.deposition),
               float(cfg.area_exponent), float(cfg.rain * cfg.channel_cells), trap)
        _settle(a, filled, trap.reshape(a.shape))
        if cfg.creep > 0:
            a = _diffuse(a, boundary, float(cfg.creep), 1.0, 1.0)
    return a * step


# ---------------------------------------------------------------------------- thermal
@nb.njit(cache=True)
def _thermal(z, iters, tan_talus, rate, dx, dy):
    r, c = z.shape
    diag = np.sqrt(dx * dx + dy * dy)
    delta = np.zeros((r, c))
    excess = np.zeros(9)
    for _ in range(iters):
        delta[:] = 0.0
        for i in range(r):
            for j in range(c):
                tot = 0.0
                big = 0.0
                for q in range(9):
                    di, dj = q // 3 - 1, q % 3 - 1
                    ii, jj = i + di, j + dj
                    excess[q] = 0.0
                    if q == 4 or ii < 0 or jj < 0 or ii >= r or jj >= c:
                        continue
                    dist = diag if di != 0 and dj != 0 else (dx if di == 0 else dy)
                    ex = z[i, j] - z[ii, jj] - tan_talus * dist
                    if ex > 0:
                        excess[q] = ex
                        tot += ex
                        big = max(big, ex)
                if tot <= 0:
                    continue
                move = rate * 0.5 * big
                for q in range(9):
                    if excess[q] > 0:
                        delta[i + q // 3 - 1, j + q % 3 - 1] += move * excess[q] / tot
                delta[i, j] -= move
        for i in range(r):
            for j in range(c):
                z[i, j] += delta[i, j]
    return z


def thermal_erosion(z, *, spacing=1.0, config: ErosionConfig | None = None) -> np.ndarray:
    """Musgrave et al. (1989) thermal weathering: slopes steeper than ``talus_deg`` shed
    half their excess height (times ``thermal_rate``) to their lower neighbours, in
    proportion to each one's excess, ``iterations`` times. Mass is conserved."""
    cfg = config or ErosionConfig()
    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    steps = THERMAL_STEPS if cfg.iterations is None else int(cfg.iterations)
    return _thermal(z.copy(), steps, float(np.tan(np.radians(cfg.talus_deg))),
                    float(cfg.thermal_rate), dx, dy)


def erode(z, *, spacing=1.0, kind: str = "stream-power",
          config: ErosionConfig | None = None) -> np.ndarray:
    """Erode ``z`` with the model ``kind`` (one of :data:`KINDS`); ``none`` copies it."""
    kind = check_choice(kind, "erosion", KINDS)
    if config is not None and not isinstance(config, ErosionConfig):
        raise ValueError(f"config: expected an ErosionConfig, got {type(config).__name__}")
    fn = {"stream-power": stream_power, "hydraulic": hydraulic_erosion,
          "thermal": thermal_erosion}.get(kind)
    if fn is None:
        return check_array(z, "heights", shape=(None, None)).copy()
    return fn(z, spacing=spacing, config=config)
