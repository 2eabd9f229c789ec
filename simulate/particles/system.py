"""Particle systems: births, forces, integration, collisions, deaths and attributes.

A :class:`ParticleSystem` advances frame by frame (``dt`` per frame, ``substeps``
integrator steps per frame). Particles interacting only with fields (gravity, wind,
turbulence, attractors, vortices, damping, buoyancy) are integrated by one fused
compiled kernel per step (:func:`advance_local`: every stage of the method in
registers, parallel over particles); pairwise forces and springs go through the
generic integrators of :mod:`simulate.integrators` over the whole state.

Note on numba's cache: the fused kernel inlines the force kernel of :mod:`simulate.forces` when it
is compiled, but numba keys its on-disk cache on this file only. After changing the
force kernels, touch this file (or clear ``simulate/particles/__pycache__``) so it recompiles.

Attributes (colour, size, opacity, mass) are :class:`Ramp` functions of age, life
fraction or temperature; temperature relaxes to ``ambient`` with time constant
``cooling_time``. Particles die at the end of their lifetime, inside a
:class:`Sink`, or behind a :class:`KillPlane`. A non-finite state stops the run with
:class:`NonFiniteStateError` naming the step and the particle.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numba as nb
import numpy as np

from core.validate import check_choice, check_int, check_positive
from simulate.collisions import CollisionStats, ContactParams, collide
from simulate.forces import ForceSet, _accel_inline
from simulate.integrators import METHODS, check_step, integrate_adaptive
from simulate.integrators import step as generic_step
from simulate.neighbours import threads_for
from simulate.particles.emitters import Emitter

log = logging.getLogger(__name__)

__all__ = ["ParticleSystem", "Ramp", "Look", "Sink", "KillPlane", "NonFiniteStateError",
           "advance_local", "FrameStats"]



class NonFiniteStateError(RuntimeError):
    """A particle's position or velocity became NaN or infinite."""

    def __init__(self, step: int, particle: int, time: float):
        # step: 1-based number of the integrator step that produced it; time: its start
        self.step, self.particle, self.time = step, particle, time
        super().__init__(f"non-finite state at step {step} (t = {time:.6g} s), particle id "
                         f"{particle}: the run was stopped (reduce the step size or check the "
                         "forces)")


# The fused methods as explicit Runge-Kutta stages whose Butcher matrix has one entry a
# row, on the sub-diagonal: stage s starts from y + h alpha_s k_(s-1) at t + alpha_s h,
# and y advances by h sum_s b_s k_s. Symplectic Euler is Euler's stage with the
# position advanced by the new velocity.
_STAGES = {
    "euler": ((0.0,), (1.0,)),
    "symplectic_euler": ((0.0,), (1.0,)),
    "midpoint": ((0.0, 0.5), (0.0, 1.0)),
    "heun": ((0.0, 1.0), (0.5, 0.5)),
    "rk4": ((0.0, 0.5, 0.5, 1.0), (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)),
}


@nb.njit(cache=True, fastmath=True)
def _advance_one(i, alpha, beta, symplectic, codes, params, perms, t, h, nsub, x, v, inv_m,
                 temp):
    """Particle ``i``'s substeps; one call site of the force kernel, inlined into it.

    Its own (non-parallel) function: numba's parallel passes over a loop body this large
    would take far longer to compile than the kernel itself."""
    px = x[i, 0]
    py = x[i, 1]
    pz = x[i, 2]
    ux = v[i, 0]
    uy = v[i, 1]
    uz = v[i, 2]
    im = inv_m[i]
    tp = temp[i]
    tt = t
    for _ in range(nsub):
        kx = ky = kz = 0.0  # the previous stage's velocity ...
        ax = ay = az = 0.0  # ... and acceleration
        sx = sy = sz = 0.0
        svx = svy = svz = 0.0
        for s in range(alpha.shape[0]):
            c = alpha[s] * h
            wx = ux + c * ax
            wy = uy + c * ay
            wz = uz + c * az
            ax, ay, az = _accel_inline(codes, params, perms, tt + c, px + c * kx, py + c * ky,
                                pz + c * kz, wx, wy, wz, im, tp)
            kx = wx
            ky = wy
            kz = wz
            sx += beta[s] * wx
            sy += beta[s] * wy
            sz += beta[s] * wz
            svx += beta[s] * ax
            svy += beta[s] * ay
            svz += beta[s] * az
        ux += h * svx
        uy += h * svy
        uz += h * svz
        if symplectic:
            px += h * ux
            py += h * uy
            pz += h * uz
        else:
            px += h * sx
            py += h * sy
            pz += h * sz
        tt += h
    x[i, 0] = px
    x[i, 1] = py
    x[i, 2] = pz
    v[i, 0] = ux
    v[i, 1] = uy
    v[i, 2] = uz


@nb.njit(parallel=True, cache=True)
def _advance(alpha, beta, symplectic, codes, params, perms, t, h, nsub, x, v, inv_m, temp):
    for i in nb.prange(x.shape[0]):
        _advance_one(i, alpha, beta, symplectic, codes, params, perms, t, h, nsub, x, v,
                     inv_m, temp)


def advance_local(forces: ForceSet, t: float, x: np.ndarray, v: np.ndarray, mass, h: float, *,
                  method: str = "rk4", substeps: int = 1, temperature=None) -> None:
    """Advance ``x, v (n, 3)`` in place by ``substeps`` steps of ``h`` under local forces.

    The fused equivalent of :func:`simulate.integrators.step` on ``y = [x, v]`` with
    ``f = [v, forces.accel(t, x, v)]`` (same arithmetic, one pass over memory).
    """
    check_choice(method, "method", tuple(_STAGES))
    if not forces.is_local:
        raise ValueError("forces: advance_local needs local forces only (no pairwise, springs)")
    n = len(x)
    inv_m = np.ascontiguousarray(1.0 / np.broadcast_to(np.asarray(mass, np.float64), (n,)))
    temp = np.ascontiguousarray(np.broadcast_to(
        np.asarray(0.0 if temperature is None else temperature, np.float64), (n,)))
    if x.dtype != np.float64 or not x.flags.c_contiguous or v.dtype != np.float64 \
            or not v.flags.c_contiguous:
        raise ValueError("x, v: expected C-contiguous float64 arrays (updated in place)")
    alpha, beta = _STAGES[method]
    with threads_for(n):
        _advance(np.array(alpha), np.array(beta), method == "symplectic_euler", forces.codes,
                 forces.params, forces.perms, float(t), float(h), int(substeps), x, v, inv_m,
                 temp)


@dataclass(frozen=True)
class Ramp:
    """A piecewise-linear attribute: ``values`` at ``x`` positions of the variable ``by``.

    ``by``: ``"life"`` (age / lifetime, 0..1), ``"age"`` (s) or ``"temperature"``.
    ``values``: ``(k,)`` scalars or ``(k, c)`` vectors (colours).
    """

    x: tuple = (0.0, 1.0)
    values: tuple = (1.0, 1.0)
    by: str = "life"

    def __post_init__(self):
        check_choice(self.by, "by", ("life", "age", "temperature"))
        xs = np.asarray(self.x, np.float64)
        vals = np.asarray(self.values, np.float64)
        if xs.ndim != 1 or len(xs) < 1 or vals.shape[:1] != xs.shape:
            raise ValueError(f"values: expected one value per x position ({len(xs)}), got "
                             f"shape {vals.shape}")
        if np.any(np.diff(xs) < 0):
            raise ValueError(f"x: expected increasing positions, got {list(self.x)}")

    def __call__(self, age, life, temp):
        var = {"life": age / life, "age": age, "temperature": temp}[self.by]
        xs = np.asarray(self.x, np.float64)
        vals = np.asarray(self.values, np.float64)
        if vals.ndim == 1:
            return np.interp(var, xs, vals)
        return np.stack([np.interp(var, xs, vals[:, c]) for c in range(vals.shape[1])], 1)


@dataclass(frozen=True)
class Look:
    """How an emitter's particles look: colour, world radius (m), opacity, mass factor.

    ``palette``: colours picked at random per birth batch (per burst), multiplied by
    ``color``.
    """

    color: Ramp | None = None
    size: Ramp | None = None
    alpha: Ramp | None = None
    mass: Ramp | None = None
    palette: tuple | None = None


@dataclass(frozen=True)
class Sink:
    """A region that deletes particles: ``kind="sphere"`` (center, radius) or ``"box"``."""

    kind: str = "sphere"
    center: tuple = (0.0, 0.0, 0.0)
    radius: float = 0.1
    lo: tuple = (0.0, 0.0, 0.0)
    hi: tuple = (0.0, 0.0, 0.0)

    def contains(self, x):
        check_choice(self.kind, "kind", ("sphere", "box"))
        if self.kind == "sphere":
            return np.linalg.norm(x - np.asarray(self.center, float), axis=1) < self.radius
        return np.all((x >= np.asarray(self.lo, float)) & (x <= np.asarray(self.hi, float)), 1)


@dataclass(frozen=True)
class KillPlane:
    """Deletes particles behind the plane: ``(x - point) . normal < 0``."""

    point: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)

    def contains(self, x):
        return (x - np.asarray(self.point, float)) @ np.asarray(self.normal, float) < 0


@dataclass
class FrameStats:
    """What happened in one frame."""

    frame: int
    time: float
    alive: int
    born: int
    died: int
    impacts: int = 0
    resting: int = 0
    escapes: int = 0
    kinetic: float = 0.0
    potential: float = 0.0


_FIELDS = ("x", "v", "age", "lifetime", "mass0", "mass", "temperature0", "temperature", "id",
           "kind", "base_color", "side")


@dataclass
class ParticleSystem:
    """A particle system advanced frame by frame.

    Parameters
    ----------
    emitters : list of Emitter
    forces : ForceSet
    rng : numpy.random.Generator
    dt : float
        Frame duration (s).
    substeps : int
        Integrator steps per frame.
    method : str
        One of :data:`simulate.integrators.METHODS`.
    collider : simulate.colliders.MeshCollider, optional
    contact : ContactParams
    sinks, kill_planes : lists of Sink / KillPlane
    looks : dict emitter name -> Look
    cooling_time, ambient : float
        Temperature relaxes as ``ambient + (T0 - ambient) exp(-age / cooling_time)``.
    max_particles : int
        Births beyond this many live particles are dropped (and counted).
    """

    emitters: list
    forces: ForceSet
    rng: np.random.Generator
    dt: float = 1.0 / 24.0
    substeps: int = 4
    method: str = "rk4"
    collider: object = None
    contact: ContactParams = field(default_factory=ContactParams)
    sinks: list = field(default_factory=list)
    kill_planes: list = field(default_factory=list)
    looks: dict = field(default_factory=dict)
    cooling_time: float = float("inf")
    ambient: float = 0.0
    max_particles: int = 2_000_000

    def __post_init__(self):
        check_choice(self.method, "method", METHODS)
        check_positive(self.dt, "dt")
        check_int(self.substeps, "substeps")
        names = [e.name for e in self.emitters]
        if len(set(names)) != len(names):
            raise ValueError(f"emitters: expected unique names, got {names}")
        for e in self.emitters:
            if not isinstance(e, Emitter):
                raise ValueError(f"emitters: expected Emitter objects, got {type(e).__name__}")
            if e.burst_of is not None and e.burst_of not in names:
                raise ValueError(f"emitters.{e.name}.burst_of: expected one of {names}, "
                                 f"got {e.burst_of!r}")
        self.t = 0.0
        self.frame_index = 0
        self.step_index = 0
        self.next_id = 0
        self.dropped = 0
        self.state = {
            "x": np.zeros((0, 3)), "v": np.zeros((0, 3)), "age": np.zeros(0),
            "lifetime": np.zeros(0), "mass0": np.zeros(0), "mass": np.zeros(0),
            "temperature0": np.zeros(0), "temperature": np.zeros(0),
            "id": np.zeros(0, np.int64), "kind": np.zeros(0, np.int64),
            "base_color": np.zeros((0, 3)), "side": np.zeros(0, bool)}
        h = self.dt / self.substeps
        masses = [e.mass for e in self.emitters] or [1.0]
        rate, omega = self.forces.stiffness(np.array(masses))
        check_step(self.method, h, rate=rate, omega=omega, what="dt / substeps")

    # -- state ---------------------------------------------------------------------
    @property
    def count(self) -> int:
        return len(self.state["x"])

    def add(self, kind: int, batch: dict, *, color=None) -> None:
        """Append particles drawn by an emitter (``batch`` from :meth:`Emitter.spawn`)."""
        n = len(batch["x"])
        room = self.max_particles - self.count
        if n > room:
            self.dropped += n - max(room, 0)
            n = max(room, 0)
            batch = {k: val[:n] for k, val in batch.items()}
        if n == 0:
            return
        side = (self.collider.inside(batch["x"]) if self.collider is not None
                and self.collider.closed else np.zeros(n, bool))
        new = {"x": batch["x"], "v": batch["v"], "age": np.zeros(n),
               "lifetime": batch["lifetime"], "mass0": batch["mass"], "mass": batch["mass"],
               "temperature0": batch["temperature"], "temperature": batch["temperature"],
               "id": np.arange(self.next_id, self.next_id + n), "kind": np.full(n, kind),
               "base_color": np.tile(np.ones(3) if color is None else color, (n, 1)),
               "side": side}
        self.next_id += n
        for k in _FIELDS:
            self.state[k] = np.concatenate([self.state[k], np.asarray(new[k],
                                                                      self.state[k].dtype)])

    def _keep(self, mask):
        for k in _FIELDS:
            self.state[k] = self.state[k][mask]

    def _palette_color(self, emitter):
        look = self.looks.get(emitter.name)
        if look is None or not look.palette:
            return None
        pal = np.asarray(look.palette, np.float64)
        return pal[self.rng.integers(len(pal))]

    # -- dynamics ------------------------------------------------------------------
    def _integrate(self, h):
        s = self.state
        x0, v0 = s["x"].copy(), s["v"].copy()
        if self.forces.is_local and self.method in _STAGES:
            x, v = s["x"].copy(), s["v"].copy()
            advance_local(self.forces, self.t, x, v, s["mass"], h, method=self.method,
                          temperature=s["temperature"])
        else:
            m, temp = s["mass"], s["temperature"]

            def f(t, y):
                return np.stack([y[1], self.forces.accel(t, y[0], y[1], m, temperature=temp)])

            y0 = np.stack([x0, v0])
            if self.method == "adaptive":
                y = integrate_adaptive(f, self.t, y0, self.t + h, rtol=1e-6, atol=1e-9)[0]
            else:
                y = generic_step(f, self.t, y0, h, method=self.method)
            x, v = y[0], y[1]
        return x0, v0, x, v

    def _check_finite(self, x, v):
        bad = ~(np.all(np.isfinite(x), axis=1) & np.all(np.isfinite(v), axis=1))
        if bad.any():
            i = int(np.argmax(bad))
            raise NonFiniteStateError(self.step_index + 1, int(self.state["id"][i]), self.t)

    def _update_attributes(self):
        s = self.state
        if np.isfinite(self.cooling_time):
            s["temperature"] = self.ambient + (s["temperature0"] - self.ambient) * np.exp(
                -s["age"] / self.cooling_time)
        for k, e in enumerate(self.emitters):
            look = self.looks.get(e.name)
            if look is None or look.mass is None:
                continue
            sel = s["kind"] == k
            if sel.any():
                s["mass"][sel] = s["mass0"][sel] * look.mass(s["age"][sel], s["lifetime"][sel],
                                                             s["temperature"][sel])

    def step_frame(self) -> FrameStats:
        """Advance one frame: births, ``substeps`` steps, deaths, bursts."""
        born = 0
        for k, e in enumerate(self.emitters):
            n = e.births(self.t, self.rng)
            if n:
                self.add(k, e.spawn(n, self.rng), color=self._palette_color(e))
                born += n
        self._update_attributes()
        h = self.dt / self.substeps
        cstats = CollisionStats()
        fused_all = (self.collider is None and self.forces.is_local and self.method in _STAGES
                     and not np.isfinite(self.cooling_time))
        if fused_all and self.count:  # no per-step work in between: all substeps at once
            s = self.state
            x, v = s["x"].copy(), s["v"].copy()
            advance_local(self.forces, self.t, x, v, s["mass"], h, method=self.method,
                          substeps=self.substeps, temperature=s["temperature"])
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
                x, v = s["x"].copy(), s["v"].copy()  # redo step by step to name the step
                for k in range(self.substeps):
                    advance_local(self.forces, self.t + k * h, x, v, s["mass"], h,
                                  method=self.method, temperature=s["temperature"])
                    self._check_finite(x, v)
                    self.step_index += 1
            self.step_index += self.substeps - 1
            s["x"], s["v"] = x, v
            s["age"] += self.dt
            self.t += self.dt
            self.step_index += 1
        else:
            for _ in range(self.substeps):
                if self.count:
                    x0, v0, x, v = self._integrate(h)
                    self._check_finite(x, v)
                    if self.collider is not None:
                        side = self.state["side"] if self.collider.closed else None
                        x, v, st = collide(self.collider, x0, v0, x, v, h, self.contact,
                                           inside=side)
                        cstats.impacts += st.impacts
                        cstats.resting += st.resting
                    self.state["x"], self.state["v"] = x, v
                    self.state["age"] += h
                    if np.isfinite(self.cooling_time):
                        self._update_attributes()
                self.t += h
                self.step_index += 1
        escapes = 0
        s = self.state
        if self.collider is not None and self.collider.closed and self.count:
            # beyond float32 resolution on the wrong side (contacts sit ~1e-10 off faces)
            tol = 1e-6 * float(np.linalg.norm(np.ptp(self.collider.bounds, axis=0)))
            sd = self.collider.signed_distance(s["x"])
            escapes = int(np.count_nonzero(np.where(s["side"], sd > tol, sd < -tol)))
        dead = s["age"] >= s["lifetime"]
        for sink in [*self.sinks, *self.kill_planes]:
            dead |= sink.contains(s["x"])
        died = int(dead.sum())
        bursts = []
        if died:
            for k, e in enumerate(self.emitters):
                if e.burst_of is None:
                    continue
                src = [i for i, o in enumerate(self.emitters) if o.name == e.burst_of][0]
                sel = np.nonzero(dead & (s["kind"] == src) & (s["age"] >= s["lifetime"]))[0]
                for i in sel:
                    n = self.rng.normal(e.rate, e.rate_std) if e.rate_std > 0 else e.rate
                    n = int(max(0.0, np.rint(n)))
                    if n:
                        bursts.append((k, e.spawn(n, self.rng, at=np.tile(s["x"][i], (n, 1)),
                                                  base_velocity=np.tile(s["v"][i], (n, 1))),
                                       self._palette_color(e)))
            self._keep(~dead)
        for k, batch, color in bursts:
            self.add(k, batch, color=color)
            born += len(batch["x"])
        self.frame_index += 1
        s = self.state
        g = np.zeros(3)
        for code, row in zip(self.forces.codes, self.forces.params, strict=True):
            if code == 0:
                g += row[:3]
        kin = float(0.5 * np.sum(s["mass"] * np.einsum("ij,ij->i", s["v"], s["v"])))
        pot = float(-np.sum(s["mass"] * (s["x"] @ g)))
        return FrameStats(self.frame_index, self.t, self.count, born, died, cstats.impacts,
                          cstats.resting, escapes, kin, pot)

    # -- output --------------------------------------------------------------------
    def frame(self) -> dict:
        """The current particles for output and rendering.

        Returns
        -------
        dict with ``points (n, 3)``, ``ids (n,)``, ``velocity (n, 3)``, ``age (n,)``,
        ``temperature (n,)``, ``colors (n, 3)``, ``sizes (n,)`` (world radius, m),
        ``alphas (n,)``, ``emitter (n,)``.
        """
        s = self.state
        n = self.count
        colors = s["base_color"].copy()
        sizes = np.full(n, 0.01)
        alphas = np.ones(n)
        for k, e in enumerate(self.emitters):
            look = self.looks.get(e.name)
            if look is None:
                continue
            sel = s["kind"] == k
            if not sel.any():
                continue
            args = (s["age"][sel], s["lifetime"][sel], s["temperature"][sel])
            if look.color is not None:
                colors[sel] = colors[sel] * look.color(*args)
            if look.size is not None:
                sizes[sel] = look.size(*args)
            if look.alpha is not None:
                alphas[sel] = look.alpha(*args)
        return {"points": s["x"].copy(), "ids": s["id"].copy(), "velocity": s["v"].copy(),
                "age": s["age"].copy(), "temperature": s["temperature"].copy(),
                "colors": np.clip(colors, 0, 1), "sizes": sizes, "alphas": np.clip(alphas, 0, 1),
                "emitter": s["kind"].copy()}

