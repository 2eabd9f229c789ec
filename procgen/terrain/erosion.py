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

**Hydraulic** (Musgrave, Kolb & Mace 1989): rain falls on every cell, water runs to
lower neighbours, dissolves the bed where it can carry more than it does, drops its load
where it slows or pools, and evaporates. It runs in cell units (heights over the grid
step) so a rate means the same on a 10 m and a 10 km terrain.

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
    area_exponent: float = option(0.5, range="(0, 2)", help="stream power: m")
    slope_exponent: float = option(1.0, range="(0, 4)", help="stream power: n")
    uplift: float | None = option(None, unit="m/yr", range="[0, inf)",
                                  help="stream power: rock uplift rate; default: the rate "
                                       "whose steady state keeps the input's relief")
    diffusivity: float | None = option(None, unit="m2/yr", range="[0, inf)",
                                       help="stream power: hillslope diffusivity; default "
                                            "1e-3 grid steps squared per year")
    iterations: int = option(400, range="[1, 100000]",
                             help="hydraulic and thermal: simulation steps")
    rain: float = option(0.01, range="[0, inf)",
                         help="hydraulic: water added per step, in grid steps of depth")
    capacity: float = option(0.1, range="[0, inf)",
                             help="hydraulic: sediment a unit of moving water can carry")
    dissolving: float = option(0.3, range="[0, 1]",
                               help="hydraulic: share of the missing capacity picked up a step")
    deposition: float = option(0.3, range="[0, 1]",
                               help="hydraulic: share of the excess sediment dropped a step")
    evaporation: float = option(0.02, range="[0, 1)",
                                help="hydraulic: share of the water evaporated a step")
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
def _hydraulic(a, iters, rain, kc, ks, kd, ke):
    r, c = a.shape
    w = np.zeros((r, c))
    s = np.zeros((r, c))
    dw = np.zeros((r, c))
    ds = np.zeros((r, c))
    drop = np.zeros(9)
    for _ in range(iters):
        for i in range(r):
            for j in range(c):
                w[i, j] += rain
        dw[:] = 0.0
        ds[:] = 0.0
        for i in range(r):
            for j in range(c):
                h = a[i, j] + w[i, j]
                tot = 0.0
                big = 0.0
                for q in range(9):
                    di, dj = q // 3 - 1, q % 3 - 1
                    ii, jj = i + di, j + dj
                    drop[q] = 0.0
                    if q == 4 or ii < 0 or jj < 0 or ii >= r or jj >= c:
                        continue
                    dh = h - a[ii, jj] - w[ii, jj]
                    if dh > 0:
                        drop[q] = dh
                        tot += dh
                        big = max(big, dh)
                if tot <= 0.0 or w[i, j] <= 0.0:
                    dep = kd * s[i, j]      # still water drops what it carries
                    a[i, j] += dep
                    s[i, j] -= dep
                    continue
                move = min(w[i, j], 0.5 * big)
                cap = kc * move
                if s[i, j] >= cap:
                    dep = kd * (s[i, j] - cap)
                    a[i, j] += dep
                    s[i, j] -= dep
                    carry = cap
                else:
                    ero = ks * (cap - s[i, j])
                    a[i, j] -= ero
                    s[i, j] += ero
                    carry = s[i, j]
                dw[i, j] -= move
                ds[i, j] -= carry
                for q in range(9):
                    if drop[q] > 0:
                        f = drop[q] / tot
                        dw[i + q // 3 - 1, j + q % 3 - 1] += move * f
                        ds[i + q // 3 - 1, j + q % 3 - 1] += carry * f
        for i in range(r):
            for j in range(c):
                w[i, j] = (w[i, j] + dw[i, j]) * (1.0 - ke)
                s[i, j] += ds[i, j]
                if i == 0 or j == 0 or i == r - 1 or j == c - 1:
                    w[i, j] = 0.0   # water and its load leave the terrain at the edge
                    s[i, j] = 0.0
    # what is still suspended settles where it is
    return a + s


def hydraulic_erosion(z, *, spacing=1.0, config: ErosionConfig | None = None) -> np.ndarray:
    """Musgrave et al. (1989) grid hydraulic erosion of ``z`` (metres) for
    ``config.iterations`` steps, in cell units (heights over the grid step).

    Each step it rains; each cell's water moves toward its lower neighbours (by water
    surface, in proportion to the drop) up to half the largest drop; the water moved can
    carry ``capacity`` times its volume of sediment: a cell dissolves ``dissolving`` of
    what is missing from its bed or drops ``deposition`` of the excess, and still water
    drops its load. Water evaporates; what reaches the grid edge leaves with its load.
    """
    cfg = config or ErosionConfig()
    z = check_array(z, "heights", shape=(None, None))
    dx, dy = _spacing(spacing)
    step = float(np.sqrt(dx * dy))
    a = np.ascontiguousarray(z / step)
    out = _hydraulic(a.copy(), int(cfg.iterations), float(cfg.rain), float(cfg.capacity),
                     float(cfg.dissolving), float(cfg.deposition), float(cfg.evaporation))
    return out * step


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
    return _thermal(z.copy(), int(cfg.iterations), float(np.tan(np.radians(cfg.talus_deg))),
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
