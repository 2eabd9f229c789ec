"""Boids: Reynolds' steering behaviours and Couzin's zone model, at scale, around meshes.

Two rule sets share one neighbour search (a uniform grid with boids sorted by cell,
:mod:`simulate.neighbours`) and one world (a bounded box, triangle-mesh obstacles):

``"reynolds"``
    Separation, alignment and cohesion (each with a radius and weight), wander, goal
    seeking and leader following; steering forces ``desired - velocity`` truncated to
    ``max_force``, speeds kept in ``[min_speed, max_speed]`` (Reynolds 1987, 1999).
``"couzin"``
    Zones of repulsion, orientation and attraction (``zor <= zoo <= zoa``); repulsion
    takes priority; constant speed, a maximum turning rate and angular noise
    (Couzin et al. 2002) — gives the swarm, torus and parallel phases.

Both perceive neighbours within a distance and a field-of-view cone (``fov_deg``;
360 sees all round, Couzin's blind angle is ``360 - fov_deg``).

Obstacles (:class:`simulate.colliders.MeshCollider`): each boid probes ahead along its
heading; a boid whose probe hits casts a cone of rays and steers toward the free
direction closest to its heading. Then every step's motion is cast as a swept segment:
a boid whose segment meets the mesh stops ``skin`` before the surface and its velocity
is reflected, so no boid passes through a mesh.

:func:`step` runs on the grid; ``method="reference"`` finds neighbours by testing all
n^2 pairs in numpy (tests compare the two to 1e-10; benchmarks use it as the naive peer).

References
----------
C. W. Reynolds, "Flocks, herds and schools: a distributed behavioral model",
SIGGRAPH 1987. doi:10.1145/37401.37406
C. W. Reynolds, "Steering behaviors for autonomous characters", GDC 1999.
I. D. Couzin, J. Krause, R. James, G. D. Ruxton, N. R. Franks, "Collective memory and
spatial sorting in animal groups", J. Theor. Biol. 218 (2002). doi:10.1006/jtbi.2002.3065
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numba as nb
import numpy as np

from core.files import read_toml, require
from core.validate import InputError, check_array, check_choice, check_int, check_range
from simulate.neighbours import build_grid, threads_for

log = logging.getLogger(__name__)

__all__ = ["BoidParams", "FlockState", "init_flock", "step", "perception_radius",
           "load_recipe", "recipe_names", "Recipe"]

MODELS = ("reynolds", "couzin")
METHODS = ("grid", "reference")
_CELLS_PER_RADIUS = 1


@dataclass(frozen=True)
class BoidParams:
    """Behaviour parameters. Lengths in metres, times in seconds, angles in degrees.

    Attributes
    ----------
    model : {"reynolds", "couzin"}
    dt : float
        Time step (s).
    fov_deg : float
        Full field-of-view cone in (0, 360]; neighbours behind it are not perceived.
    separation_radius, alignment_radius, cohesion_radius : float
        Reynolds perception radii (> 0).
    separation_weight, alignment_weight, cohesion_weight : float
        Reynolds weights (>= 0).
    max_speed, min_speed : float
        Speed limits (Reynolds), ``0 <= min_speed <= max_speed``, ``max_speed > 0``.
    max_force : float
        Largest steering acceleration (m/s^2).
    wander_weight, wander_jitter_deg : float
        Wander: a per-boid random-walk direction, jittered by this angle a step.
    goal : (3,) float or None
        A point to seek with ``goal_weight`` (leaders only, when there are leaders).
    leaders, leader_weight, leader_distance : int, float, float
        The first ``leaders`` boids lead; the others seek a point ``leader_distance``
        behind the nearest leader.
    zor, zoo, zoa : float
        Couzin radii of the zones of repulsion, orientation, attraction.
    turning_rate_deg : float
        Couzin maximum turning rate (degrees per second).
    speed : float
        Couzin constant speed.
    noise_deg : float
        Couzin angular noise (standard deviation, degrees a step).
    avoid_weight : float
        Weight of obstacle avoidance (Reynolds).
    look_ahead : float
        Probe length in seconds of travel at the current speed.
    probe_rays, probe_angle_deg : int, float
        The avoidance cone: ``probe_rays`` directions on rings up to this half-angle.
    skin : float
        Distance kept from a mesh surface when a swept segment is stopped.
    bounds : ((3,), (3,)) or None
        World box ``(lo, hi)``; boids are steered back within ``bounds_margin`` of a
        wall (``bounds_weight``) and reflected at it.
    """

    model: str = "reynolds"
    dt: float = 0.1
    fov_deg: float = 270.0
    separation_radius: float = 1.0
    alignment_radius: float = 2.5
    cohesion_radius: float = 4.0
    separation_weight: float = 1.5
    alignment_weight: float = 1.0
    cohesion_weight: float = 1.0
    max_speed: float = 2.0
    min_speed: float = 0.5
    max_force: float = 1.0
    wander_weight: float = 0.0
    wander_jitter_deg: float = 10.0
    goal: tuple | None = None
    goal_weight: float = 0.0
    leaders: int = 0
    leader_weight: float = 0.0
    leader_distance: float = 2.0
    zor: float = 1.0
    zoo: float = 3.0
    zoa: float = 15.0
    turning_rate_deg: float = 40.0
    speed: float = 3.0
    noise_deg: float = 2.865  # 0.05 rad, as in Couzin et al. (2002)
    avoid_weight: float = 4.0
    look_ahead: float = 1.5
    probe_rays: int = 24
    probe_angle_deg: float = 90.0
    skin: float = 1e-3
    bounds: tuple | None = ((-50.0, -50.0, -50.0), (50.0, 50.0, 50.0))
    bounds_margin: float = 2.0
    bounds_weight: float = 2.0

    def __post_init__(self):
        check_choice(self.model, "model", MODELS)
        check_range(self.dt, "dt", 0, None, lo_open=True)
        check_range(self.fov_deg, "fov_deg", 0, 360, lo_open=True)
        for name in ("separation_radius", "alignment_radius", "cohesion_radius", "zor",
                     "zoo", "zoa", "max_speed", "max_force", "speed", "look_ahead", "skin",
                     "bounds_margin", "leader_distance"):
            check_range(getattr(self, name), name, 0, None, lo_open=True)
        for name in ("separation_weight", "alignment_weight", "cohesion_weight",
                     "wander_weight", "goal_weight", "leader_weight", "avoid_weight",
                     "bounds_weight", "min_speed", "noise_deg", "turning_rate_deg"):
            check_range(getattr(self, name), name, 0, None)
        check_range(self.min_speed, "min_speed", 0, self.max_speed)
        check_range(self.wander_jitter_deg, "wander_jitter_deg", 0, 180)
        check_range(self.probe_angle_deg, "probe_angle_deg", 0, 180, lo_open=True)
        if not (self.zor <= self.zoo <= self.zoa):
            raise ValueError(f"zor, zoo, zoa: expected zor <= zoo <= zoa, got "
                             f"{self.zor}, {self.zoo}, {self.zoa}")
        object.__setattr__(self, "leaders", check_int(self.leaders, "leaders", 0))
        object.__setattr__(self, "probe_rays", check_int(self.probe_rays, "probe_rays"))
        if self.goal is not None:
            object.__setattr__(self, "goal", tuple(
                check_array(self.goal, "goal", shape=(3,)).tolist()))
        if self.bounds is not None:
            b = check_array(self.bounds, "bounds", shape=(2, 3))
            if np.any(b[1] - b[0] <= 2 * self.bounds_margin):
                raise ValueError(f"bounds: expected hi - lo > 2 * bounds_margin on every axis, "
                                 f"got lo={b[0].tolist()}, hi={b[1].tolist()}")
            object.__setattr__(self, "bounds", (tuple(b[0].tolist()), tuple(b[1].tolist())))

    def replace(self, **changes) -> BoidParams:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def perception_radius(params: BoidParams) -> float:
    """The largest distance at which a boid perceives another."""
    if params.model == "couzin":
        return params.zoa
    return max(params.separation_radius, params.alignment_radius, params.cohesion_radius)


@dataclass
class FlockState:
    """Boids' state; arrays are indexed by boid id.

    Attributes
    ----------
    positions, velocities : (n, 3) float64
    wander : (n, 3) float64
        Unit wander directions.
    time : float
    steps : int
    collisions : int
        Swept segments stopped at a mesh so far (contacts, not penetrations).
    """

    positions: np.ndarray
    velocities: np.ndarray
    wander: np.ndarray
    time: float = 0.0
    steps: int = 0
    collisions: int = field(default=0)

    def __post_init__(self):
        self.positions = check_array(self.positions, "positions", shape=(None, 3)).copy()
        n = len(self.positions)
        self.velocities = check_array(self.velocities, "velocities", shape=(n, 3)).copy()
        self.wander = check_array(self.wander, "wander", shape=(n, 3)).copy()


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _random_unit(rng, n):
    return _unit(rng.standard_normal((n, 3)))


def init_flock(n: int, params: BoidParams, *, rng: np.random.Generator,
               centre=(0.0, 0.0, 0.0), radius: float = 10.0,
               speed: float | None = None) -> FlockState:
    """Boids uniformly in a ball, with uniformly random headings.

    Parameters
    ----------
    n : int
        Number of boids (>= 1).
    centre : (3,) float
    radius : float
        Ball radius (> 0).
    speed : float, optional
        Initial speed; defaults to ``params.speed`` (Couzin) or the mean of the limits.
    """
    n = check_int(n, "n")
    c = check_array(centre, "centre", shape=(3,))
    r = check_range(radius, "radius", 0, None, lo_open=True)
    if speed is None:
        speed = params.speed if params.model == "couzin" else 0.5 * (
            params.min_speed + params.max_speed)
    s = check_range(speed, "speed", 0, None)
    d = _random_unit(rng, n)
    rad = r * rng.uniform(0, 1, n) ** (1 / 3)
    pos = c + d * rad[:, None]
    vel = _random_unit(rng, n) * s
    return FlockState(positions=pos, velocities=vel, wander=_random_unit(rng, n))


# --- parameters packed for the kernels -------------------------------------------------
_RS2, _RA2, _RC2, _WS, _WA, _WC, _VMAX, _VMIN, _FMAX, _FOVCOS = range(10)
_WW, _WG, _GX, _GY, _GZ, _NLEAD, _WL, _LDIST, _ZOR2, _ZOO2, _ZOA2 = range(10, 21)
_TURN, _SPEED, _DT, _BOUNDED, _LOX, _LOY, _LOZ, _HIX, _HIY, _HIZ, _MARGIN, _WB = range(21, 33)
_NPARAM = 33


def _pack(p: BoidParams) -> np.ndarray:
    out = np.zeros(_NPARAM)
    out[_RS2] = p.separation_radius ** 2
    out[_RA2] = p.alignment_radius ** 2
    out[_RC2] = p.cohesion_radius ** 2
    out[_WS], out[_WA], out[_WC] = p.separation_weight, p.alignment_weight, p.cohesion_weight
    out[_VMAX], out[_VMIN], out[_FMAX] = p.max_speed, p.min_speed, p.max_force
    out[_FOVCOS] = -2.0 if p.fov_deg >= 360 else math.cos(math.radians(p.fov_deg) / 2)
    out[_WW] = p.wander_weight
    if p.goal is not None:
        out[_WG] = p.goal_weight
        out[_GX:_GZ + 1] = p.goal
    out[_NLEAD], out[_WL], out[_LDIST] = p.leaders, p.leader_weight, p.leader_distance
    out[_ZOR2], out[_ZOO2], out[_ZOA2] = p.zor ** 2, p.zoo ** 2, p.zoa ** 2
    out[_TURN] = math.radians(p.turning_rate_deg) * p.dt
    out[_SPEED], out[_DT] = p.speed, p.dt
    if p.bounds is not None:
        out[_BOUNDED] = 1.0
        out[_LOX:_LOZ + 1] = p.bounds[0]
        out[_HIX:_HIZ + 1] = p.bounds[1]
    out[_MARGIN], out[_WB] = p.bounds_margin, p.bounds_weight
    return out


@nb.njit(cache=True, inline="always")
def _steer_to(dx, dy, dz, vx, vy, vz, vmax, fmax):
    """Truncated steering ``normalize(d) * vmax - v``; zero for a zero ``d``."""
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    if n == 0.0:
        return 0.0, 0.0, 0.0
    sx = dx / n * vmax - vx
    sy = dy / n * vmax - vy
    sz = dz / n * vmax - vz
    m = math.sqrt(sx * sx + sy * sy + sz * sz)
    if m > fmax:
        f = fmax / m
        return sx * f, sy * f, sz * f
    return sx, sy, sz


@nb.njit(cache=True, inline="always")
def _steer_add(ax, ay, az, weight, dx, dy, dz, vx, vy, vz, vmax, fmax):
    """``a + weight * steer_to(d)``: one weighted behaviour added to the steering."""
    sx, sy, sz = _steer_to(dx, dy, dz, vx, vy, vz, vmax, fmax)
    return ax + weight * sx, ay + weight * sy, az + weight * sz


@nb.njit(cache=True, inline="always")
def _bounds_push(x, y, z, P):
    """Inward push, growing linearly from 0 at ``margin`` inside a wall to 1 at it."""
    bx = by = bz = 0.0
    if P[_BOUNDED] > 0:
        m = P[_MARGIN]
        if x < P[_LOX] + m:
            bx += (P[_LOX] + m - x) / m
        if x > P[_HIX] - m:
            bx -= (x - P[_HIX] + m) / m
        if y < P[_LOY] + m:
            by += (P[_LOY] + m - y) / m
        if y > P[_HIY] - m:
            by -= (y - P[_HIY] + m) / m
        if z < P[_LOZ] + m:
            bz += (P[_LOZ] + m - z) / m
        if z > P[_HIZ] - m:
            bz -= (z - P[_HIZ] + m) / m
    return bx, by, bz


@nb.njit(cache=True, inline="always")
def _reynolds_finish(i, k, xs, vs, ws, x, v, P, sep, ali, coh, nsep, nali, ncoh, out):
    """Weighted steering of boid ``i`` (row ``k`` of ``xs, vs, ws, out``) from its
    neighbour sums (shared by both paths); ``x, v`` by id, for the leaders."""
    px, py, pz = xs[k, 0], xs[k, 1], xs[k, 2]
    vx, vy, vz = vs[k, 0], vs[k, 1], vs[k, 2]
    vmax = P[_VMAX]
    fmax = P[_FMAX]
    ax = ay = az = 0.0
    if nsep > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WS], sep[0], sep[1], sep[2], vx, vy, vz, vmax, fmax)
    if nali > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WA], ali[0] / nali, ali[1] / nali, ali[2] / nali,
                                vx, vy, vz, vmax, fmax)
    if ncoh > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WC], coh[0] / ncoh, coh[1] / ncoh, coh[2] / ncoh,
                                vx, vy, vz, vmax, fmax)
    if P[_WW] > 0:
        ax, ay, az = _steer_add(ax, ay, az, P[_WW], ws[k, 0], ws[k, 1], ws[k, 2],
                                vx, vy, vz, vmax, fmax)
    nlead = np.int64(P[_NLEAD])
    if i < nlead or nlead == 0:
        if P[_WG] > 0:
            ax, ay, az = _steer_add(ax, ay, az, P[_WG], P[_GX] - px, P[_GY] - py, P[_GZ] - pz,
                                    vx, vy, vz, vmax, fmax)
    elif P[_WL] > 0:
        best = -1
        bd = np.inf
        for m in range(nlead):
            dx = x[m, 0] - px
            dy = x[m, 1] - py
            dz = x[m, 2] - pz
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < bd:
                bd = d2
                best = m
        lvx, lvy, lvz = v[best, 0], v[best, 1], v[best, 2]
        ls = math.sqrt(lvx * lvx + lvy * lvy + lvz * lvz)
        tx, ty, tz = x[best, 0], x[best, 1], x[best, 2]
        if ls > 0:
            tx -= lvx / ls * P[_LDIST]
            ty -= lvy / ls * P[_LDIST]
            tz -= lvz / ls * P[_LDIST]
        ax, ay, az = _steer_add(ax, ay, az, P[_WL], tx - px, ty - py, tz - pz,
                                vx, vy, vz, vmax, fmax)
    bx, by, bz = _bounds_push(px, py, pz, P)
    out[k, 0] = ax + P[_WB] * fmax * bx
    out[k, 1] = ay + P[_WB] * fmax * by
    out[k, 2] = az + P[_WB] * fmax * bz


@nb.njit(cache=True, inline="always")
def _couzin_finish(k, xs, vs, P, dr, do, da, nr, no, na, out):
    """Desired unit direction of the boid in row ``k`` (zero: keep heading)."""
    dx = dy = dz = 0.0
    if nr > 0:
        dx, dy, dz = dr[0], dr[1], dr[2]
    else:
        on = math.sqrt(do[0] * do[0] + do[1] * do[1] + do[2] * do[2])
        an = math.sqrt(da[0] * da[0] + da[1] * da[1] + da[2] * da[2])
        if no > 0 and on > 0:
            f = 0.5 if (na > 0 and an > 0) else 1.0
            dx += f * do[0] / on
            dy += f * do[1] / on
            dz += f * do[2] / on
        if na > 0 and an > 0:
            f = 0.5 if (no > 0 and on > 0) else 1.0
            dx += f * da[0] / an
            dy += f * da[1] / an
            dz += f * da[2] / an
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    if n > 0:
        dx /= n
        dy /= n
        dz /= n
    bx, by, bz = _bounds_push(xs[k, 0], xs[k, 1], xs[k, 2], P)
    if bx != 0.0 or by != 0.0 or bz != 0.0:
        if n == 0:
            sp = math.sqrt(vs[k, 0] ** 2 + vs[k, 1] ** 2 + vs[k, 2] ** 2)
            if sp > 0:
                dx, dy, dz = vs[k, 0] / sp, vs[k, 1] / sp, vs[k, 2] / sp
        dx += P[_WB] * bx
        dy += P[_WB] * by
        dz += P[_WB] * bz
        n = math.sqrt(dx * dx + dy * dy + dz * dz)
        if n > 0:
            dx /= n
            dy /= n
            dz /= n
    out[k, 0] = dx
    out[k, 1] = dy
    out[k, 2] = dz


@nb.njit(parallel=True, cache=True)
def _gather(x, v, w, order, xs, vs, ws):
    for k in nb.prange(order.shape[0]):
        i = order[k]
        for a in range(3):
            xs[k, a] = x[i, a]
            vs[k, a] = v[i, a]
            ws[k, a] = w[i, a]


@nb.njit(parallel=True, cache=True)
def _scatter(src, order, dst):
    for k in nb.prange(order.shape[0]):
        i = order[k]
        for a in range(3):
            dst[i, a] = src[k, a]


@nb.njit(parallel=True, cache=True, error_model="numpy")
def _steer_grid(x, v, P, couzin, xs, vs, ws, order, cell, dims, start, reach, out):
    """Steering (Reynolds) or desired direction (Couzin) of every boid, on the grid.

    ``xs, vs, ws`` are positions, velocities and wander sorted by cell (``order``), and
    so is ``out``; each boid's neighbours are visited cell by cell, in a fixed order,
    by one thread.
    """
    nx, ny, nz = dims[0], dims[1], dims[2]
    fovcos = P[_FOVCOS]
    rs2, ra2, rc2 = P[_RS2], P[_RA2], P[_RC2]
    zor2, zoo2 = P[_ZOR2], P[_ZOO2]
    if couzin:
        r2max = P[_ZOA2]
    else:
        r2max = max(P[_RS2], max(P[_RA2], P[_RC2]))
    for c in nb.prange(start.shape[0] - 1):
        if start[c] == start[c + 1]:
            continue
        cx0 = c % nx
        cy0 = (c // nx) % ny
        cz0 = c // (nx * ny)
        for k in range(start[c], start[c + 1]):
            i = order[k]
            px, py, pz = xs[k, 0], xs[k, 1], xs[k, 2]
            vx, vy, vz = vs[k, 0], vs[k, 1], vs[k, 2]
            sp = math.sqrt(vx * vx + vy * vy + vz * vz)
            hx = hy = hz = 0.0
            if sp > 0:
                hx, hy, hz = vx / sp, vy / sp, vz / sp
            look = fovcos > -1.0 and sp > 0
            a0 = a1 = a2 = b0 = b1 = b2 = c0 = c1 = c2 = 0.0
            na = nb_ = nc = 0
            gx0 = max(cx0 - reach, 0)
            gx1 = min(cx0 + reach, nx - 1)
            for gz in range(max(cz0 - reach, 0), min(cz0 + reach + 1, nz)):
                for gy in range(max(cy0 - reach, 0), min(cy0 + reach + 1, ny)):
                    # cells along x are consecutive in the sorted order: one contiguous run
                    g = nx * (gy + ny * gz)
                    for kk in range(start[g + gx0], start[g + gx1 + 1]):
                        if kk == k:
                            continue
                        dx = xs[kk, 0] - px
                        dy = xs[kk, 1] - py
                        dz = xs[kk, 2] - pz
                        r2 = dx * dx + dy * dy + dz * dz
                        if r2 >= r2max:
                            continue
                        r = math.sqrt(r2)
                        if look and hx * dx + hy * dy + hz * dz < fovcos * r:
                            continue
                        if couzin:
                            if r2 < zor2:
                                if r > 0:
                                    a0 -= dx / r
                                    a1 -= dy / r
                                    a2 -= dz / r
                                na += 1
                            elif r2 < zoo2:
                                wx, wy, wz = vs[kk, 0], vs[kk, 1], vs[kk, 2]
                                wn = math.sqrt(wx * wx + wy * wy + wz * wz)
                                if wn > 0:
                                    b0 += wx / wn
                                    b1 += wy / wn
                                    b2 += wz / wn
                                nb_ += 1
                            else:
                                c0 += dx / r
                                c1 += dy / r
                                c2 += dz / r
                                nc += 1
                        else:
                            if r2 < rs2 and r2 > 0:
                                a0 -= dx / r2
                                a1 -= dy / r2
                                a2 -= dz / r2
                                na += 1
                            if r2 < ra2:
                                b0 += vs[kk, 0]
                                b1 += vs[kk, 1]
                                b2 += vs[kk, 2]
                                nb_ += 1
                            if r2 < rc2:
                                c0 += dx
                                c1 += dy
                                c2 += dz
                                nc += 1
            if couzin:
                _couzin_finish(k, xs, vs, P, (a0, a1, a2), (b0, b1, b2), (c0, c1, c2), na, nb_,
                               nc, out)
            else:
                _reynolds_finish(i, k, xs, vs, ws, x, v, P, (a0, a1, a2), (b0, b1, b2),
                                 (c0, c1, c2), na, nb_, nc, out)


@nb.njit(parallel=True, cache=True, error_model="numpy")
def _finish_all(x, v, wander, P, couzin, sums, counts, out):
    """Apply the per-boid rules to neighbour sums computed elsewhere (the reference)."""
    for i in nb.prange(x.shape[0]):
        r = (sums[i, 0, 0], sums[i, 0, 1], sums[i, 0, 2])
        o = (sums[i, 1, 0], sums[i, 1, 1], sums[i, 1, 2])
        t = (sums[i, 2, 0], sums[i, 2, 1], sums[i, 2, 2])
        if couzin:
            _couzin_finish(i, x, v, P, r, o, t, counts[i, 0], counts[i, 1], counts[i, 2], out)
        else:
            _reynolds_finish(i, i, x, v, wander, x, v, P, r, o, t, counts[i, 0], counts[i, 1],
                             counts[i, 2], out)


def _sums_reference(x, v, P, couzin, block=512):
    """Neighbour sums ``(n, 3 rules, 3)`` and counts ``(n, 3)`` over all n^2 pairs (numpy)."""
    n = len(x)
    sums = np.zeros((n, 3, 3))
    counts = np.zeros((n, 3), np.int64)
    sp = np.sqrt(v[:, 0] * v[:, 0] + v[:, 1] * v[:, 1] + v[:, 2] * v[:, 2])
    h = np.divide(v, sp[:, None], out=np.zeros_like(v), where=sp[:, None] > 0)
    vs_n = h  # unit velocities (Couzin orientation)
    r2max = P[_ZOA2] if couzin else max(P[_RS2], P[_RA2], P[_RC2])
    for a0 in range(0, n, block):
        a1 = min(a0 + block, n)
        d = x[None, :, :] - x[a0:a1, None, :]
        dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
        r2 = dx * dx + dy * dy + dz * dz
        r = np.sqrt(r2)
        m = r2 < r2max
        m[np.arange(a1 - a0), np.arange(a0, a1)] = False
        hb = h[a0:a1]
        look = (P[_FOVCOS] > -1.0) & (sp[a0:a1] > 0)
        dot = hb[:, 0:1] * dx + hb[:, 1:2] * dy + hb[:, 2:3] * dz
        m &= ~(look[:, None] & (dot < P[_FOVCOS] * r))
        rs = np.where(r > 0, r, 1.0)
        if couzin:
            mr = m & (r2 < P[_ZOR2])
            mo = m & ~mr & (r2 < P[_ZOO2])
            ma = m & ~mr & ~mo
            sums[a0:a1, 0] = -np.einsum("ij,ijk->ik", (mr & (r > 0)) / rs, d)
            sums[a0:a1, 1] = mo.astype(float) @ vs_n
            sums[a0:a1, 2] = np.einsum("ij,ijk->ik", ma / rs, d)
        else:
            mr = m & (r2 < P[_RS2]) & (r2 > 0)
            mo = m & (r2 < P[_RA2])
            ma = m & (r2 < P[_RC2])
            sums[a0:a1, 0] = -np.einsum("ij,ijk->ik", mr / np.where(r2 > 0, r2, 1.0), d)
            sums[a0:a1, 1] = mo.astype(float) @ v
            sums[a0:a1, 2] = np.einsum("ij,ijk->ik", ma.astype(float), d)
        counts[a0:a1, 0] = mr.sum(axis=1)
        counts[a0:a1, 1] = mo.sum(axis=1)
        counts[a0:a1, 2] = ma.sum(axis=1)
    return sums, counts



@nb.njit(inline="always", cache=True)
def _reflect(p, v, lo, hi):
    """Mirror a coordinate that left ``[lo, hi]`` back inside; its velocity points in."""
    if p < lo:
        return min(2 * lo - p, hi), abs(v)
    if p > hi:
        return max(2 * hi - p, lo), -abs(v)
    return p, v

@nb.njit(parallel=True, cache=True, error_model="numpy")
def _integrate(x, v, steer, noise, P, couzin, xn, vn):
    """Advance every boid one step: truncate steering (Reynolds) or turn (Couzin), move,
    reflect at the world box."""
    dt = P[_DT]
    for i in nb.prange(x.shape[0]):
        vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
        if couzin:
            s = math.sqrt(vx * vx + vy * vy + vz * vz)
            if s > 0:
                hx, hy, hz = vx / s, vy / s, vz / s
            else:
                hx, hy, hz = 1.0, 0.0, 0.0
            dx, dy, dz = steer[i, 0], steer[i, 1], steer[i, 2]
            if dx == 0.0 and dy == 0.0 and dz == 0.0:
                dx, dy, dz = hx, hy, hz
            # angular noise: a perpendicular Gaussian kick of the desired direction
            gx, gy, gz = noise[i, 0], noise[i, 1], noise[i, 2]
            gd = gx * dx + gy * dy + gz * dz
            dx += gx - gd * dx
            dy += gy - gd * dy
            dz += gz - gd * dz
            n = math.sqrt(dx * dx + dy * dy + dz * dz)
            dx /= n
            dy /= n
            dz /= n
            c = min(max(hx * dx + hy * dy + hz * dz, -1.0), 1.0)
            ang = math.acos(c)
            if ang > P[_TURN]:
                # rotate h toward d by the turning limit, in their common plane
                px, py, pz = dx - c * hx, dy - c * hy, dz - c * hz
                pn = math.sqrt(px * px + py * py + pz * pz)
                if pn < 1e-12:  # opposite: any perpendicular will do
                    if abs(hx) < 0.9:
                        px, py, pz = 0.0, -hz, hy
                    else:
                        px, py, pz = -hz, 0.0, hx
                    pn = math.sqrt(px * px + py * py + pz * pz)
                px /= pn
                py /= pn
                pz /= pn
                t = P[_TURN]
                dx = math.cos(t) * hx + math.sin(t) * px
                dy = math.cos(t) * hy + math.sin(t) * py
                dz = math.cos(t) * hz + math.sin(t) * pz
            sp = P[_SPEED]
            vx, vy, vz = dx * sp, dy * sp, dz * sp
        else:
            ax, ay, az = steer[i, 0], steer[i, 1], steer[i, 2]
            m = math.sqrt(ax * ax + ay * ay + az * az)
            if m > P[_FMAX]:
                f = P[_FMAX] / m
                ax *= f
                ay *= f
                az *= f
            vx += ax * dt
            vy += ay * dt
            vz += az * dt
            s = math.sqrt(vx * vx + vy * vy + vz * vz)
            if s > P[_VMAX]:
                f = P[_VMAX] / s
                vx *= f
                vy *= f
                vz *= f
            elif s < P[_VMIN]:
                if s > 0:
                    f = P[_VMIN] / s
                    vx *= f
                    vy *= f
                    vz *= f
                else:
                    vx = P[_VMIN]
        px = x[i, 0] + vx * dt
        py = x[i, 1] + vy * dt
        pz = x[i, 2] + vz * dt
        if P[_BOUNDED] > 0:
            px, vx = _reflect(px, vx, P[_LOX], P[_HIX])
            py, vy = _reflect(py, vy, P[_LOY], P[_HIY])
            pz, vz = _reflect(pz, vz, P[_LOZ], P[_HIZ])
        xn[i, 0], xn[i, 1], xn[i, 2] = px, py, pz
        vn[i, 0], vn[i, 1], vn[i, 2] = vx, vy, vz


def _cone(rays: int, half_angle: float) -> np.ndarray:
    """Probe directions ``(rays, 2)`` as (polar angle, azimuth), nearest the axis first."""
    rings = max(1, int(round(math.sqrt(rays / 2))))
    per = max(1, rays // rings)
    out = []
    for k in range(1, rings + 1):
        a = half_angle * k / rings
        for m in range(per):
            out.append((a, 2 * math.pi * (m + 0.5 * (k % 2)) / per))
    return np.array(out)


def _frame(h):
    """Two unit vectors ``(n, 3)`` perpendicular to unit ``h`` and each other."""
    ref = np.where(np.abs(h[:, 0:1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    u = _unit(np.cross(h, ref))
    return u, np.cross(h, u)


def _avoidance(collider, x, v, params: BoidParams):
    """Boids whose probe ahead hits the mesh, and the free direction for each.

    Returns ``(idx (m,) int64, direction (m, 3) float64, urgency (m,) float64)``;
    urgency grows from 0 (hit at the probe's end) to 1 (hit at the boid).
    """
    sp = np.linalg.norm(v, axis=1)
    h = _unit(v)
    length = params.look_ahead * np.maximum(sp, 1e-9)
    hits = collider.cast(x, h * length[:, None])
    idx = np.nonzero(hits.hit & (hits.t <= 1.0))[0]
    if len(idx) == 0:
        return idx, np.zeros((0, 3)), np.zeros(0)
    hh = h[idx]
    u, w = _frame(hh)
    cone = _cone(params.probe_rays, math.radians(params.probe_angle_deg))
    ca, sa = np.cos(cone[:, 0]), np.sin(cone[:, 0])
    cb, sb = np.cos(cone[:, 1]), np.sin(cone[:, 1])
    dirs = (ca[None, :, None] * hh[:, None, :]
            + (sa * cb)[None, :, None] * u[:, None, :]
            + (sa * sb)[None, :, None] * w[:, None, :])  # (m, rays, 3)
    m, k = dirs.shape[:2]
    L = length[idx]
    probe = collider.cast(np.repeat(x[idx], k, axis=0),
                          (dirs * L[:, None, None]).reshape(-1, 3))
    blocked = (probe.hit & (probe.t <= 1.0)).reshape(m, k)
    free = ~blocked
    # Surface normal at the forward hit, facing the boid.
    nrm = hits.normal[idx]
    nrm[np.sum(nrm * hh, axis=1) > 0] *= -1
    # The free direction nearest the heading (innermost ring); within a ring, the one
    # leading most away from the surface.
    ring = np.round(cone[:, 0] / cone[:, 0].max() * 1e3)
    score = ring[None, :] - 0.5 * np.einsum("mkc,mc->mk", dirs, nrm)
    score[blocked] = np.inf
    best = np.argmin(score, axis=1)
    out = dirs[np.arange(m), best]
    # No free direction: head along the surface normal, away from the wall.
    none = ~free.any(axis=1)
    out[none] = nrm[none]
    urgency = 1.0 - np.clip(hits.t[idx], 0.0, 1.0)
    return idx, out, urgency


def _sweep(collider, x0, x1, v1, skin):
    """Stop segments ``x0 -> x1`` that meet the mesh before it; reflect velocity.

    A stopped boid is put ``skin`` before the hit along its segment and lifted ``skin``
    off the surface along the normal (so a grazing stop is not left on the surface at
    float32 precision), unless that lift would itself meet the mesh.
    Returns the number of boids stopped.
    """
    seg = x1 - x0
    hits = collider.cast(x0, seg)
    seglen = np.linalg.norm(seg, axis=1)
    # a hit up to ``skin`` past the segment's end counts: the end must keep off the surface
    reach = 1.0 + skin / np.maximum(seglen, 1e-300)
    idx = np.nonzero(hits.hit & (hits.t <= reach))[0]
    if len(idx) == 0:
        return 0
    s = seg[idx]
    length = seglen[idx]
    t = np.minimum(np.maximum(hits.t[idx] - skin / length, 0.0), 1.0)
    stop = x0[idx] + t[:, None] * s
    n = hits.normal[idx]
    n[np.sum(n * s, axis=1) > 0] *= -1
    lift = skin * n
    blocked = collider.cast(stop, lift)
    ok = ~(blocked.hit & (blocked.t <= 1.0))
    stop[ok] += lift[ok]
    x1[idx] = stop
    vv = v1[idx]
    vn = np.sum(vv * n, axis=1)
    v1[idx] = vv - 2 * np.minimum(vn, 0.0)[:, None] * n
    return len(idx)


def step(state: FlockState, params: BoidParams, *, rng: np.random.Generator,
         collider=None, method: str = "grid") -> FlockState:
    """Advance the flock one time step (in place) and return it.

    Parameters
    ----------
    state : FlockState
    params : BoidParams
    rng : numpy.random.Generator
        Wander and noise draws (only drawn when those behaviours are on).
    collider : simulate.colliders.MeshCollider, optional
        Obstacles: probe-and-steer avoidance and a swept-segment guarantee.
    method : {"grid", "reference"}
        Neighbour search: the cell-sorted grid, or all n^2 pairs (numpy).
    """
    check_choice(method, "method", METHODS)
    with threads_for(len(state.positions)):
        return _step(state, params, rng, collider, method)


def _step(state, params, rng, collider, method):
    x = state.positions
    v = state.velocities
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
        raise ValueError("state: expected finite positions and velocities, got NaN or inf")
    n = len(x)
    P = _pack(params)
    couzin = params.model == "couzin"
    if params.wander_weight > 0 and not couzin:
        jitter = math.radians(params.wander_jitter_deg)
        state.wander = _unit(state.wander + jitter * rng.standard_normal((n, 3)))
    steer = np.empty((n, 3))
    if method == "grid":
        lo = hi = None
        if params.bounds is not None:
            lo, hi = np.array(params.bounds[0]), np.array(params.bounds[1])
        radius = perception_radius(params)
        # cells one radius wide (3^3 per boid): measured faster than half-radius cells (5^3)
        grid = build_grid(x, radius / _CELLS_PER_RADIUS, lo=lo, hi=hi)
        reach = int(math.ceil(radius / grid.cell_size))
        xs = np.empty_like(x)
        vs = np.empty_like(v)
        ws = np.empty_like(v)
        _gather(x, v, state.wander, grid.order, xs, vs, ws)
        sorted_steer = np.empty_like(x)
        _steer_grid(x, v, P, couzin, xs, vs, ws, grid.order, grid.cell, grid.dims,
                    grid.start, reach, sorted_steer)
        _scatter(sorted_steer, grid.order, steer)
    else:
        sums, counts = _sums_reference(x, v, P, couzin)
        _finish_all(x, v, state.wander, P, couzin, sums, counts, steer)
    if collider is not None:
        idx, free, urgency = _avoidance(collider, x, v, params)
        if len(idx):
            if couzin:
                steer[idx] = free
            else:
                desired = free * params.max_speed - v[idx]
                m = np.linalg.norm(desired, axis=1, keepdims=True)
                desired *= np.minimum(1.0, params.max_force / np.maximum(m, 1e-300))
                # prioritized: the nearer the wall, the less the other behaviours count
                steer[idx] = ((1.0 - urgency)[:, None] * steer[idx]
                              + params.avoid_weight * desired)
    if couzin and params.noise_deg > 0:
        noise = math.radians(params.noise_deg) * rng.standard_normal((n, 3))
    else:
        noise = np.zeros((1, 3)) if not couzin else np.zeros((n, 3))
    xn = np.empty_like(x)
    vn = np.empty_like(v)
    _integrate(x, v, steer, noise, P, couzin, xn, vn)
    if collider is not None:
        state.collisions += _sweep(collider, x, xn, vn, params.skin)
    state.positions = xn
    state.velocities = vn
    state.time += params.dt
    state.steps += 1
    return state


# --- recipes -----------------------------------------------------------------------------
_RECIPES = Path(__file__).parent / "boid_recipes"
_FIELDS = {f.name: f for f in dataclasses.fields(BoidParams)}
_OBSTACLES = ("none", "sphere", "torus", "scan")


@dataclass(frozen=True)
class Recipe:
    """A named simulation: behaviour parameters and run settings.

    Attributes
    ----------
    name : str
    params : BoidParams
    n, steps, seed : int
    init_radius : float
        Boids start in a ball of this radius about ``init_centre``.
    init_centre : (3,) float
    frame_every : int
        Write a frame (VTP, animation) every this many steps.
    group_radius : float
        Two boids closer than this are in one group (metrics).
    obstacle : {"none", "sphere", "torus", "scan"}
        Procedural stand-in used when no mesh is given.
    obstacle_size : float
        Its radius (m).
    """

    name: str
    params: BoidParams
    n: int = 200
    steps: int = 500
    seed: int = 0
    init_radius: float = 10.0
    init_centre: tuple = (0.0, 0.0, 0.0)
    frame_every: int = 5
    group_radius: float = 4.0
    obstacle: str = "none"
    obstacle_size: float = 5.0


def recipe_names() -> list[str]:
    """Names of the shipped recipes."""
    return sorted(p.stem for p in _RECIPES.glob("*.toml"))


def _int(table, key, path, prefix, default, lo=1):
    v = require(table, key, int, path=path, prefix=prefix, default=default)
    if v < lo:
        raise InputError(f"expected an integer >= {lo}, got {v}", path=path,
                         field=f"{prefix}.{key}")
    return v


def load_recipe(name_or_path: str | os.PathLike) -> Recipe:
    """A shipped recipe by name (see :func:`recipe_names`) or a TOML file.

    The file holds ``[boids]`` (fields of :class:`BoidParams`) and ``[run]`` (the other
    fields of :class:`Recipe`). Errors name the file and the field.
    """
    s = str(name_or_path)
    path = Path(s)
    if not path.suffix and (_RECIPES / f"{s}.toml").is_file():
        path = _RECIPES / f"{s}.toml"
    elif not path.is_file():
        raise InputError(f"expected a shipped recipe ({', '.join(recipe_names())}) or a "
                         "TOML file", path=s)
    data = read_toml(path)
    unknown = set(data) - {"boids", "run"}
    if unknown:
        raise InputError(f"unknown table(s) {sorted(unknown)}; expected [boids] and [run]",
                         path=path)
    boids = require(data, "boids", dict, path=path, default={})
    run = require(data, "run", dict, path=path, default={})
    kwargs = {}
    for key in boids:
        if key not in _FIELDS:
            raise InputError(f"unknown field; expected one of {', '.join(sorted(_FIELDS))}",
                             path=path, field=f"boids.{key}")
        if key in ("leaders", "probe_rays"):
            kwargs[key] = _int(boids, key, path, "boids", None, lo=0)
        elif key == "model":
            kwargs[key] = require(boids, key, str, path=path, prefix="boids")
        elif key in ("goal", "bounds"):  # an empty list: none (open world, no goal)
            kwargs[key] = require(boids, key, list, path=path, prefix="boids") or None
        else:
            kwargs[key] = require(boids, key, float, path=path, prefix="boids")
    try:
        params = BoidParams(**kwargs)
    except ValueError as exc:
        msg = str(exc)
        fld = msg.split(":", 1)[0]
        raise InputError(msg.split(": ", 1)[-1], path=path, field=f"boids.{fld}") from None
    known = {"n", "steps", "seed", "init_radius", "init_centre", "frame_every",
             "group_radius", "obstacle", "obstacle_size"}
    for key in run:
        if key not in known:
            raise InputError(f"unknown field; expected one of {', '.join(sorted(known))}",
                             path=path, field=f"run.{key}")
    centre = require(run, "init_centre", list, path=path, prefix="run", default=[0.0, 0, 0])
    try:
        centre = tuple(check_array(centre, "init_centre", shape=(3,)).tolist())
    except ValueError as exc:
        raise InputError(str(exc).split(": ", 1)[-1], path=path, field="run.init_centre") \
            from None
    obstacle = require(run, "obstacle", str, path=path, prefix="run", default="none")
    if obstacle not in _OBSTACLES:
        raise InputError(f"expected one of {', '.join(_OBSTACLES)}, got {obstacle!r}",
                         path=path, field="run.obstacle")
    pos = {}
    for key, default in (("init_radius", 10.0), ("group_radius", 4.0),
                         ("obstacle_size", 5.0)):
        pos[key] = require(run, key, float, path=path, prefix="run", default=default)
        if not (math.isfinite(pos[key]) and pos[key] > 0):
            raise InputError(f"expected a number > 0, got {pos[key]}", path=path,
                             field=f"run.{key}")
    return Recipe(name=path.stem, params=params,
                  n=_int(run, "n", path, "run", 200),
                  steps=_int(run, "steps", path, "run", 500),
                  seed=_int(run, "seed", path, "run", 0, lo=0),
                  frame_every=_int(run, "frame_every", path, "run", 5),
                  init_centre=centre, obstacle=obstacle, **pos)
