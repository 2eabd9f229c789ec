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

The model is this module; its compiled kernels are :mod:`simulate.boids._kernels`, and
named recipes of parameters are :mod:`simulate.boids.recipes`.

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
from dataclasses import dataclass, field

import numpy as np

from core.frames import unit
from core.validate import check_array, check_choice, check_int, check_range
from simulate.boids._kernels import (
    _finish_all,
    _gather,
    _integrate,
    _pack,
    _scatter,
    _steer_grid,
    _sums_reference,
)
from simulate.neighbours import build_grid, threads_for

log = logging.getLogger(__name__)

__all__ = ["BoidParams", "FlockState", "init_flock", "step", "perception_radius", "MODELS",
           "METHODS"]

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


def _random_unit(rng, n):
    return unit(rng.standard_normal((n, 3)))


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
    u = unit(np.cross(h, ref))
    return u, np.cross(h, u)


def _avoidance(collider, x, v, params: BoidParams):
    """Boids whose probe ahead hits the mesh, and the free direction for each.

    Returns ``(idx (m,) int64, direction (m, 3) float64, urgency (m,) float64)``;
    urgency grows from 0 (hit at the probe's end) to 1 (hit at the boid).
    """
    sp = np.linalg.norm(v, axis=1)
    h = unit(v)
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
        state.wander = unit(state.wander + jitter * rng.standard_normal((n, 3)))
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
